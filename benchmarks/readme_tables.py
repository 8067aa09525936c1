"""Print the benchmark tables of docs/bench.md (Markdown) from a `hconv bench --json` file.

python benchmarks/readme_tables.py docs/bench.json
"""

import json
import sys

with open(sys.argv[1] if len(sys.argv) > 1 else "docs/bench.json") as f:
    res = json.load(f)
user = res.get("user", {})
engines = list(dict.fromkeys(e for t in user.values() for v in t.values() if isinstance(v, dict) for e in v))
if user:
    print("| rows | I, diagnostics | numpy.linalg.solve | " + " | ".join(engines) + " |")
    print("|---" * (3 + len(engines)) + "|")
    for n, times in user.items():
        solve = times["numpy.linalg.solve"]
        first = True
        for call, by in times.items():
            if call == "numpy.linalg.solve":
                continue
            size = f"{int(n):,}" if n.isdigit() else n
            t = f"{solve * 1e6:.1f} µs" if solve < 1e-3 else f"{solve * 1e3:.1f} ms"
            cells = [size if first else "", call, t if first else ""]
            cells += [f"{solve / by[e]:.2f}" if e in by else "" for e in engines]
            print("| " + " | ".join(cells) + " |")
            first = False
    print()
    for name, c in res.get("cold", {}).items():
        print(
            f"- first call, {name}: import {c['import_s']:.2f} s, first call {c['first_call_s']:.3f} s, "
            f"second {c['second_call_s'] * 1e3:.2f} ms"
        )
    print()
conds = list(next(iter(res["accuracy"].values())))
lapack = res["kernel"]["lapack/64"]


def err(x):
    m, w = x

    def one(v):
        return "0" if v == 0 else f"{v:.0e}"

    return "flagged" if m is None or m != m else f"{one(m)} / {one(w)}"


print(
    "| method | prec | kernel Mrows/s | × lapack | convert Mrows/s | "
    + " | ".join(f"error at cond {float(c):g}, median / worst" for c in conds)
    + " |"
)
print("|---" * (5 + len(conds)) + "|")
for key, speed in res["kernel"].items():
    name, prec = key.split("/")
    cells = [name, prec, f"{speed / 1e6:.3g}", f"{speed / lapack:.3g}", f"{res['convert'][key] / 1e6:.3g}"]
    print("| " + " | ".join(cells + [err(res["accuracy"][key][c]) for c in conds]) + " |")
print()
print("| target | measured | required | met |")
print("|---|---|---|---|")
for name, value, required, met in res["targets"]:
    print(
        f"| {name} | {'skipped' if value is None else f'{value:.2f}'} | ≥ {required:g} | "
        f"{'—' if met is None else ('yes' if met else '**no**')} |"
    )
b = res["baselines"]
print(
    f"\nroofline {b['io_roofline_rows_per_s'] / 1e6:.2f} M rows/s; plain script {b['plain_script_s']:.2f} s; "
    f"hconv convert {b['hconv_convert_cli_s']:.2f} s; "
    f"compiled loop {b['compiled_loop_rows_per_s'] / 1e6:.0f} M rows/s; "
    f"exact kernel in a fresh process {b['exact_kernel_fresh_process_rows_per_s'] / 1e6:.1f} M rows/s; "
    f"peak RSS {b.get('peak_rss_mb', float('nan')):.0f} MB on {b.get('memory_rows', 0):,} rows"
)
