"""The README and every page of docs/ run top to bottom: every shell, console and Python block, in
order, each page in its own fresh copy of the repository, as a newcomer runs it; a console block
prints what it shows on an 80-column terminal; afterwards git sees nothing new (every file the
commands write is ignored), and every link points inside the repository. (docs/recipes.md is
tests/test_recipes.py's: its blocks are the recipe files, run there with their engines.)"""

from __future__ import annotations

import fcntl
import json
import os
import pty
import re
import shutil
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The pages whose blocks run here: the README first, then docs/ (recipes.md: see the docstring).
PAGES = ["README.md", *(f"docs/{p.name}" for p in sorted((ROOT / "docs").glob("*.md")) if p.name != "recipes.md")]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
#: The languages of code blocks: these run, and ``text`` (output, a message) is only shown.
RUN = ("sh", "console", "python")
# The set-up block's install and test run are what CI itself does with the README (.ci/run); here
# they would reinstall into this environment and run this suite inside itself. The benchmarks take
# minutes on a quiet machine and are never run by the tests (CONTRIBUTING.md).
SET_UP_ONLY = re.compile(
    r"^(python3 -m venv |\.venv/bin/pip install |pip install |\.venv/bin/python -m pytest"
    r"|bash benchmarks/run\.sh|python benchmarks/(?!readme_tables\.py))"
)


def blocks(text: str) -> list[tuple[str, str]]:
    """(language, body) of every fenced block, in order."""
    return [(m.group(1), m.group(2)) for m in FENCE.finditer(text)]


def without_set_up_only(body: str) -> str:
    """``body`` without the install and test commands (each line split at ``&&``)."""
    lines = []
    for line in body.splitlines():
        kept = [part.strip() for part in line.split("&&") if not SET_UP_ONLY.match(part.strip())]
        if kept:
            lines.append(" && ".join(kept))
    return "\n".join(lines)


def console(body: str) -> list[tuple[str, list[str]]]:
    """(command, the lines the page shows it printing) for each ``$`` line of a console block."""
    out: list[tuple[str, list[str]]] = []
    for line in body.splitlines():
        if line.startswith("$ "):
            out.append((line[2:], []))
        else:
            out[-1][1].append(line)
    return out


@pytest.fixture(scope="module")
def repository(tmp_path_factory) -> Path:
    """A copy of the repository's files as they stand (committed or not) in a fresh git repository."""
    if shutil.which("git") is None:
        pytest.skip("needs git")
    dst = tmp_path_factory.mktemp("repository") / "hconv"
    listed = subprocess.run(
        ["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=ROOT, capture_output=True, check=True
    ).stdout.decode()
    for name in filter(None, listed.split("\0")):
        if (ROOT / name).is_file():
            (dst / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, dst / name)
    subprocess.run([*GIT, "init", "-q"], cwd=dst, check=True)
    subprocess.run([*GIT, "add", "-A"], cwd=dst, check=True)
    subprocess.run([*GIT, "commit", "-q", "-m", "readme"], cwd=dst, check=True)
    return dst


GIT = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-c", "commit.gpgsign=false"]


def fresh_clone(repository: Path, dst: Path) -> Path:
    """A clone of ``repository`` at ``dst``, with ``.venv/bin/hconv`` and ``.venv/bin/python``
    running this test's interpreter."""
    subprocess.run([*GIT, "clone", "-q", str(repository), str(dst)], check=True)
    bin_dir = dst / ".venv" / "bin"
    bin_dir.mkdir(parents=True)
    for name, run in (("hconv", f'"{sys.executable}" -m hconv'), ("python", f'"{sys.executable}"')):
        (bin_dir / name).write_text(f'#!/bin/sh\nexec {run} "$@"\n')
        (bin_dir / name).chmod(0o755)
    return dst


def _run(command: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PATH=f"{cwd / '.venv' / 'bin'}{os.pathsep}{os.environ['PATH']}", PYTHONUNBUFFERED="1")
    return subprocess.run(
        ["bash", "-eu", "-c", command],  # no pipefail: `| head` stops its writer, as users expect
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        timeout=300,
    )


def _on_terminal(command: str, cwd: Path) -> tuple[int, list[str]]:
    """Run ``command`` with stdout and stderr on an 80-column pseudo-terminal, as the pages'
    console blocks show it; returns the exit code and the lines a reader sees (no colour codes)."""
    main, side = pty.openpty()
    fcntl.ioctl(side, termios.TIOCSWINSZ, struct.pack("HHHH", 50, 80, 0, 0))
    env = dict(os.environ, PATH=f"{cwd / '.venv' / 'bin'}{os.pathsep}{os.environ['PATH']}", COLUMNS="80")
    env.pop("NO_COLOR", None)
    proc = subprocess.Popen(["bash", "-eu", "-c", command], cwd=cwd, env=env, stdout=side, stderr=side)
    os.close(side)
    seen = b""
    while True:
        try:
            chunk = os.read(main, 65536)
        except OSError:  # the terminal closes when the command and its children have exited
            break
        if not chunk:
            break
        seen += chunk
    os.close(main)
    code = proc.wait(timeout=300)
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", seen.decode()).replace("\r", "")
    return code, [line.rstrip() for line in text.rstrip("\n").splitlines()]


def runnable(text: str) -> list[tuple[str, str]]:
    """The blocks a page's test runs, in order: ``sh`` without its set-up-only lines (and none
    left empty by them), every ``console`` and ``python`` block."""
    out = []
    for lang, body in blocks(text):
        if lang == "sh":
            body = without_set_up_only(body)
        if lang in RUN and body.strip():
            out.append((lang, body))
    return out


@pytest.mark.parametrize("page", PAGES)
def test_docs_every_block_runs_in_order_in_a_fresh_clone(page, repository, tmp_path):
    text = (ROOT / page).read_text(encoding="utf-8")
    unknown = [lang for lang, _ in blocks(text) if lang not in (*RUN, "text")]
    assert unknown == [], f"{page}: give every block a language: {', '.join(RUN)} run, text is shown only"
    todo = runnable(text)
    if not todo:
        return
    clone = fresh_clone(repository, tmp_path / "hconv")
    ran = 0
    for lang, body in todo:
        if lang == "sh":
            proc = _run(body, clone)
            assert proc.returncode == 0, f"{page} block failed:\n{body}\n---\n{proc.stdout.decode()}"
            assert "hconv: error" not in proc.stdout.decode(), f"{page} block failed in a pipe:\n{body}"
            ran += 1
        elif lang == "console":
            for command, shown in console(body):
                code, printed = _on_terminal(command, clone)
                assert code == 0, f"$ {command}\n" + "\n".join(printed)
                assert printed == shown, f"$ {command} prints something else than {page} shows"
                ran += 1
        else:
            proc = _run(f"python - <<'PY'\n{body}\nPY", clone)
            assert proc.returncode == 0, f"{page} block failed:\n{body}\n---\n{proc.stdout.decode()}"
            ran += 1
    if page == "README.md":
        assert ran >= 5  # the set-up, the tour and the API's minute are here, not lost by a broken fence
    left = subprocess.run(["git", "status", "--porcelain"], cwd=clone, capture_output=True, check=True)
    assert left.stdout.decode() == "", f"files {page}'s commands write are not in .gitignore"


def test_runnable_skips_text_and_set_up_only_blocks():
    text = "```sh\npip install .\n```\n```text\nhconv: error: x\n```\n```sh\nhconv methods\n```\n"
    assert runnable(text) == [("sh", "hconv methods")]


@pytest.mark.parametrize("page", [*PAGES, "docs/recipes.md", "CONTRIBUTING.md"])
def test_docs_links_stay_in_the_repository(page):
    text = (ROOT / page).read_text(encoding="utf-8")
    folder = (ROOT / page).parent
    for target in re.findall(r"\]\(([^)#]+)[^)]*\)", text):
        if not re.match(r"https?://", target):
            path = (folder / target).resolve()
            assert path.is_relative_to(ROOT), f"{page} links to {target}, outside the repository"
            assert path.exists(), f"{page} links to {target}, which is not in the repository"


def test_without_set_up_only_keeps_the_example_and_drops_install_and_tests():
    body = "python3 -m venv .venv && .venv/bin/pip install -e '.[test]' && hconv one --H 1\n.venv/bin/python -m pytest"
    assert without_set_up_only(body) == "hconv one --H 1"


def test_docs_one_json_keys_are_the_ones_printed(tmp_path):
    text = (ROOT / "docs" / "commands.md").read_text(encoding="utf-8")
    said = text.split("`--json` prints", 1)[1].split("with `null`", 1)[0]
    printed: set[str] = set()
    for args in ("--H 1,2,3 --I 1,2,3", "--H 1,1,0 --I 0,1,1 --degenerate pinv"):
        proc = subprocess.run(
            [sys.executable, "-m", "hconv", "one", *args.split(), "--json"],
            capture_output=True,
            check=True,
            cwd=tmp_path,
        )
        printed |= set(json.loads(proc.stdout))
    assert set(re.findall(r'"(\w+)"', said)) == printed
