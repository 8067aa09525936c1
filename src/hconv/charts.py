"""Charts, drawn with matplotlib (the optional extra ``hconv[plot]``, imported only here)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from hconv.errors import UsageError

if TYPE_CHECKING:
    from hconv.tools.bench import Result as BenchResult
    from hconv.tools.stability import Point, Sweep


#: Errors are drawn on log axes; an error of exactly 0 (correctly rounded) is drawn here.
FLOOR = 1e-18


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise UsageError(
            "charts need matplotlib: pip install matplotlib (hconv's plot extra), or pass --no-chart"
        ) from None
    return plt


def requested(out: str | None, no_chart: bool) -> str | None:
    """The chart path a command should write, or None; UsageError now, before a long run, if the
    name is not .png/.svg or matplotlib is missing. matplotlib itself (slow to import) is
    loaded only when a chart is drawn."""
    if no_chart or out is None:
        return None
    if not out.lower().endswith((".png", ".svg")):
        raise UsageError(f"--out {out!r}: name the chart .png or .svg")
    import importlib.util

    if importlib.util.find_spec("matplotlib") is None:
        raise UsageError("charts need matplotlib: pip install matplotlib (hconv's plot extra), or pass --no-chart")
    return out


def stability_chart(points: list[Point], sweeps: tuple[Sweep, ...], path: str) -> None:
    """One panel per sweep: worst error against the sweep parameter, log axes, a line per method
    and precision (solid float64, dashed float32); hollow markers where most rows are flagged."""
    plt = _pyplot()
    from hconv.solve.methods import METHODS

    names = list(METHODS)
    colours = {n: plt.get_cmap("tab10")(k) for k, n in enumerate(names)}
    fig, axes = plt.subplots(2, 3, figsize=(17, 10), constrained_layout=True)
    for ax, sw in zip(axes.flat, sweeps):
        params = np.asarray(sw.params, dtype=float)
        positive = params[params > 0]
        zero_at = positive.min() / 100 if (params == 0).any() else None
        for name in names:
            for prec, style in ((64, "-"), (32, "--")):
                pts = [p for p in points if p.sweep == sw.name and p.method == name and p.precision == prec]
                x = np.array([p.param if p.param > 0 else zero_at for p in pts])
                y = np.array([max(p.worst_error, FLOOR) if np.isfinite(p.worst_error) else np.nan for p in pts])
                flagged = np.array([p.flagged >= 0.5 for p in pts])
                ax.plot(
                    x,
                    y,
                    style,
                    color=colours[name],
                    lw=1.4,
                    alpha=0.9,
                    label=f"{name} ({'float64' if prec == 64 else 'float32'})",
                )
                ax.scatter(x[~flagged], y[~flagged], s=16, color=colours[name], zorder=3)
                ax.scatter(x[flagged], y[flagged], s=22, facecolors="none", edgecolors=[colours[name]], zorder=3)
        for level, text in ((2.2e-16, "float64 eps"), (1.2e-7, "float32 eps"), (1e-6, "1e-6: flag beyond")):
            ax.axhline(level, color="grey", lw=0.8, ls=":")
            ax.text(
                0.99, level, text, transform=ax.get_yaxis_transform(), ha="right", va="bottom", fontsize=8, color="grey"
            )
        if sw.log_x:
            ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylim(FLOOR / 3, 1e3)
        if zero_at is not None:
            ticks = [t for t in ax.get_xticks() if positive.min() <= t <= positive.max()]
            ax.set_xticks([zero_at] + ticks[::2], ["0"] + [f"1e{int(np.log10(t))}" for t in ticks[::2]])
            ax.set_xlim(zero_at / 3, positive.max() * 3)
        if sw.params[0] > sw.params[-1]:
            ax.invert_xaxis()
        ax.set_title(sw.title, fontsize=12)
        ax.set_xlabel(sw.xlabel)
        ax.set_ylabel("worst relative error vs I⁻¹H")
        ax.grid(True, which="major", alpha=0.3)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(
        handles,
        labels,
        loc="outside right center",
        fontsize=9,
        title="solid float64, dashed float32\nhollow: most rows flagged\nat the floor: correctly rounded",
    )
    fig.suptitle("hconv stability: where each method stops being trustworthy", fontsize=14)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def speed_accuracy_chart(res: BenchResult, path: str, cond: str = "10000") -> None:
    """Accuracy (worst error at ``cond``, log) against what a user gets (rows/s, log, every
    diagnostic): ``hconv convert``'s throughput Parquet to Parquet, one point per method and
    precision; and ``hconv.convert``'s on the largest in-memory batch, one point per engine; with
    the Pareto front (nothing both faster and more accurate). The kernels' own speed is in the
    tables, not here."""
    plt = _pyplot()
    from hconv.solve.methods import METHODS

    colours = {n: plt.get_cmap("tab10")(k) for k, n in enumerate(METHODS)}
    pts = []
    for key, speed in res.convert.items():
        name, prec = key.split("/")
        err = res.accuracy[key][cond][1]
        if np.isfinite(err):
            pts.append((speed, max(err, FLOOR), name, int(prec)))
    fig, ax = plt.subplots(figsize=(12, 7.5), constrained_layout=True)
    labels = []  # (speed, err, text, side): placed once every point is drawn (_place_labels)
    for speed, err, name, prec in sorted(pts, key=lambda p: (round(np.log10(p[1])), p[0])):
        ax.scatter(
            speed,
            err,
            s=90,
            marker="o" if prec == 64 else "s",
            color=colours[name],
            edgecolors="black",
            linewidths=0.6,
            zorder=3,
        )
        labels.append((speed, err, f"{name} f{prec}", 1))
    # hconv.convert in memory, with every diagnostic, engine by engine: exact's error is the same
    # bits in every engine, so each engine is one more point at exact's accuracy
    big = max((n for n in res.user if n.isdigit()), key=int, default=None)
    if big is not None and "exact/64" in res.accuracy:
        err = max(res.accuracy["exact/64"][cond][1], FLOOR)
        for engine, secs in res.user[big].get("(N,3,3)", {}).items():
            speed = int(big) / secs
            ax.scatter(
                speed, err, s=110, marker="^", color=colours["exact"], edgecolors="black", linewidths=0.6, zorder=3
            )
            text = "hconv.convert, by default (compiled)" if engine == "auto" else f"hconv.convert, {engine} engine"
            labels.append((speed, err, text, -1))
            pts.append((speed, err, "exact", 64))
    front, best = [], np.inf
    for speed, err, _name, _prec in sorted(pts, key=lambda p: -p[0]):
        if err < best:
            front.append((speed, err))
            best = err
    fx, fy = zip(*front)
    ax.step(
        fx,
        fy,
        where="post",
        color="black",
        lw=1.2,
        ls="--",
        label="Pareto front: nothing is both faster and more accurate",
    )
    for level, text in ((2.2e-16, "float64 eps"), (1.2e-7, "float32 eps"), (1e-6, "1e-6")):
        ax.axhline(level, color="grey", lw=0.8, ls=":")
        ax.text(
            0.995, level, text, transform=ax.get_yaxis_transform(), ha="right", va="bottom", fontsize=8, color="grey"
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(
        "rows per second with every diagnostic (fastest of repeats)\n"
        "hconv convert, Parquet to Parquet (circles, squares); hconv.convert on (N,3,3) in memory (triangles)"
    )
    ax.set_ylabel(f"worst relative error vs exact I⁻¹H at cond(I) = {float(cond):g}")
    ax.set_ylim(FLOOR / 3, 10)
    ax.set_xlim(*ax.get_xlim())  # final, so that the labels can be placed in the picture's pixels
    ax.grid(True, which="major", alpha=0.3)
    legend = ax.legend(
        loc="center", fontsize=9, title="circles float64, squares float32\nat the floor: correctly rounded"
    )
    ax.set_title(f"hconv: speed against accuracy, {res.rows:,} rows\n{res.machine}", fontsize=11)
    _place_labels(fig, ax, labels, legend)
    fig.savefig(path, dpi=90)
    plt.close(fig)


#: Where a label may go beside its point, in points (x, y), tried in this order; x's sign is the
#: side the text extends to.
_PLACES = ((7, 6), (7, -14), (-7, 6), (-7, -14), (7, 20), (7, -28), (-7, 20), (-7, -28))
#: Where it goes when none of those is free, with a line to its point: farther out, around it.
_FAR = tuple(
    (round(r * np.cos(a)), round(r * np.sin(a)))
    for r in (35, 55, 80, 110)
    for a in np.radians((-30, 30, -60, 60, -150, 150, -120, 120))
)


def _place_labels(fig: Any, ax: Any, labels: list, legend: Any = None) -> None:
    """Each label ``(x, y, text, side)`` at the first of :data:`_PLACES` (those on ``side`` first)
    where it stays inside the axes and covers no label placed before it, no point and not the
    legend, and where the point nearest the side of its text that faces it is its own; else at
    the first such place of :data:`_FAR` (nearness aside), with a line to its point. Points close
    in speed have labels as wide as the gap between them: a rule on the points' distances alone
    overprinted, and one without the nearness test set labels beside the wrong points."""
    from matplotlib.text import Text

    fig.canvas.draw()  # the layout (title, axis labels, legend) as it will be saved
    renderer = fig.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    blocked = [legend.get_window_extent(renderer)] if legend is not None else []
    points = ax.transData.transform([(x, y) for x, y, _text, _side in labels])
    for k, (x, y, text, side) in enumerate(labels):
        near = sorted(_PLACES, key=lambda p: (p[0] > 0) != (side > 0))
        tries = [(p, False) for p in near] + [(p, True) for p in _FAR]
        for t, ((dx, dy), far) in enumerate(tries):
            label = ax.annotate(
                text,
                (x, y),
                textcoords="offset points",
                xytext=(dx, dy),
                ha="left" if dx > 0 else "right",
                va="center" if far else "baseline",
                fontsize=9,
                arrowprops={"arrowstyle": "-", "color": "grey", "lw": 0.6, "shrinkB": 5} if far else None,
            )
            label.set_in_layout(False)
            # the text's own box (an Annotation's includes its line), where the offset puts it
            label.update_positions(renderer)
            box = Text.get_window_extent(label, renderer).expanded(1.02, 1.1)
            facing = np.array([box.x0 if dx > 0 else box.x1, (box.y0 + box.y1) / 2])  # the side by the point
            reach = np.hypot(*(points - facing).T)
            fits = (
                frame.x0 <= box.x0
                and box.x1 <= frame.x1
                and frame.y0 <= box.y0
                and box.y1 <= frame.y1
                and not any(box.overlaps(b) for b in blocked)
                and not any(box.x0 - 4 < px < box.x1 + 4 and box.y0 - 4 < py < box.y1 + 4 for px, py in points)
                and (far or reach[k] * 1.3 < np.delete(reach, k).min(initial=np.inf))
            )
            if fits or t == len(tries) - 1:
                blocked.append(box)
                break
            label.remove()
