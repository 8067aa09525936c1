"""The package's structure as a contract: the layers (import-linter), no reaching into another
module's private names, and docs/architecture.md, the one description of the structure, naming
every module and only modules that exist. (``hconv one`` staying free of pyarrow and rich is
tested in test_cli.py, and declared in pyproject.toml's contract too.)"""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parent.parent / "src" / "hconv"
ARCHITECTURE = SRC.parent.parent / "docs" / "architecture.md"


def _modules():
    for path in sorted(SRC.rglob("*.py")):
        parts = path.relative_to(SRC.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        yield name, ast.parse(path.read_text(), str(path))


def _private_uses(name: str, tree: ast.AST) -> list[str]:
    """``from hconv.x import _y`` and ``x._y`` (x an imported hconv module other than this one)."""
    found, aliases = [], {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("hconv"):
            for a in node.names:
                target = f"{node.module}.{a.name}"
                if a.name.startswith("_") and not a.name.startswith("__") and node.module != name:
                    found.append(f"{name}: from {node.module} import {a.name}")
                aliases[a.asname or a.name] = target
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("hconv"):
                    aliases[a.asname or a.name.split(".")[0]] = a.name
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.attr.startswith("_")
            and not node.attr.startswith("__")
            and node.value.id in aliases
            and aliases[node.value.id] != name
        ):
            found.append(f"{name}: {node.value.id}.{node.attr}")
    return found


def test_modules_use_no_other_modules_private_names():
    found = [use for name, tree in _modules() for use in _private_uses(name, tree)]
    assert found == []


def test_private_name_check_finds_a_planted_reach():
    planted = ast.parse("from hconv.kernels import eft\nfrom hconv.solve.methods import _x\ny = eft._split()\n")
    assert _private_uses("hconv.tools.bench", planted) == [
        "hconv.tools.bench: from hconv.solve.methods import _x",
        "hconv.tools.bench: eft._split",
    ]


@pytest.mark.skipif(
    shutil.which("lint-imports", path=str(Path(sys.executable).parent)) is None,
    reason="import-linter is installed with the test extra",
)
def test_layers_contract_holds():
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    proc = subprocess.run([exe], capture_output=True, text=True, cwd=SRC.parent.parent, timeout=120)
    assert proc.returncode == 0, proc.stdout[-2000:]
    assert "0 broken" in proc.stdout


def _module_table(text: str) -> list[str]:
    """The modules listed in architecture.md's "Modules" table, as paths under src/hconv/."""
    section = text.split("\n## Modules\n", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^\| `([\w/]+\.py)` \|", section, re.M)


def test_architecture_module_table_lists_every_module_once_and_no_other():
    listed = _module_table(ARCHITECTURE.read_text(encoding="utf-8"))
    real = sorted(path.relative_to(SRC).as_posix() for path in SRC.rglob("*.py"))
    assert sorted(set(listed)) == sorted(listed), "a module is listed twice"
    assert sorted(listed) == real


def test_architecture_names_only_modules_that_exist():
    """Every ``kernels/x.py``, ``solve/x.py``, ``tables/x.py`` or ``tools/x.py`` the page names,
    in any section, is a module."""
    named = set(re.findall(r"\b((?:kernels|solve|tables|tools)/\w+\.py)", ARCHITECTURE.read_text(encoding="utf-8")))
    assert named and sorted(name for name in named if not (SRC / name).is_file()) == []


def test_module_table_reads_a_planted_table():
    text = "\n## Modules\n\n| module | what |\n|---|---|\n| `cli.py` | x |\n| `solve/rows.py` | y |\n"
    text += "\n## Next\n\n| `a.py` | z |\n"
    assert _module_table(text) == ["cli.py", "solve/rows.py"]
