"""wearbench.model's seams are public: no ``_name`` of a model module is used outside that module.

Read from the source of every module of the repository (the library, benchmarks, experiments, tests):
``from wearbench.model.X import _y``, ``M._y`` where M names a model module (``from wearbench.model import
kernel as K``, ``import wearbench.model.kernel``) and ``setattr(M, "_y", ...)`` (a monkeypatch) all count.
What crosses a file has a public, documented name (issue 47, item 4).
"""

from __future__ import annotations

import ast
import os
from pathlib import Path

import pytest

pytestmark = pytest.mark.no_kernels

ROOT = Path(__file__).resolve().parents[2]
SKIP = {".venv", ".git", "build", "dist", "__pycache__"}


def _model_aliases(tree: ast.Module) -> dict[str, str]:
    """Names bound to a module of wearbench.model (or to a name imported from one): name -> dotted target."""
    aliases = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("wearbench.model"):
            for a in node.names:
                aliases[a.asname or a.name] = f"{node.module}.{a.name}"
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("wearbench.model"):
                    aliases[a.asname or a.name.split(".")[0]] = a.name
    return aliases


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def private_uses(source: str) -> list[str]:
    """Every use of a model module's underscore name in ``source``, as ``line: what``."""
    tree = ast.parse(source)
    aliases = _model_aliases(tree)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("wearbench.model"):
            found += [f"{node.lineno}: from {node.module} import {a.name}" for a in node.names if _private(a.name)]
        elif isinstance(node, ast.Attribute) and _private(node.attr):
            base = ast.unparse(node.value)
            if base in aliases or base.startswith("wearbench.model"):
                found.append(f"{node.lineno}: {base}.{node.attr}")
        elif (isinstance(node, ast.Call) and ast.unparse(node.func).endswith("setattr") and len(node.args) >= 2
              and isinstance(node.args[1], ast.Constant) and isinstance(node.args[1].value, str)
              and _private(node.args[1].value) and ast.unparse(node.args[0]) in aliases):
            found.append(f"{node.lineno}: setattr({ast.unparse(node.args[0])}, {node.args[1].value!r})")
    return found


def _sources() -> list[Path]:
    """Every *.py of the checkout, virtual environments and build output left out (not walked into)."""
    found = []
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = sorted(d for d in dirs if d not in SKIP and not d.startswith(".venv"))
        found += [Path(folder) / f for f in sorted(files) if f.endswith(".py")]
    return found


def test_no_module_uses_a_private_name_of_the_model():
    bad = {}
    for path in _sources():
        uses = private_uses(path.read_text(encoding="utf-8"))
        if uses:
            bad[str(path.relative_to(ROOT))] = uses
    assert bad == {}


@pytest.mark.parametrize(("source", "expected"), [
    ("from wearbench.model.scene import _dense_jacobian\n", ["1: from wearbench.model.scene import _dense_jacobian"]),
    ("from wearbench.model import kernel as K\nK._schur(1, 2, 3)\n", ["2: K._schur"]),
    ("import wearbench.model.kernel\nwearbench.model.kernel._schur(1)\n", ["2: wearbench.model.kernel._schur"]),
    ("from wearbench.model import simulation as S\nmonkeypatch.setattr(S, '_STEPS', 3)\n",
     ["2: setattr(S, '_STEPS')"]),
    # public names, dunders, a record's own methods (namedtuple's _replace) are no private use
    ("from wearbench.model import kernel as K\nK.schur(1, 2, 3)\nK.__name__\nK.Model(1)._replace(P=2)\n", []),
    ("import numpy as np\nnp._NoValue\n", []),
])
def test_the_check_catches_a_private_use(source, expected):
    assert private_uses(source) == expected
