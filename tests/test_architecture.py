"""The layers of wearbench point down: each package imports only the layers below it, and no two
modules import each other (directly or round a longer circle). Read from the source, every import
counted (also those inside functions), so a lazy import cannot hide an upward edge.

The rules are the README's "Architecture" section; this test is their owner.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("bench", "model", "hardware", "acquisition", "validation", "cli", "testing")

# layer -> the layers it may import (itself always allowed)
ALLOWED: dict[str, set[str]] = {
    "bench": set(),
    "model": {"bench"},
    "hardware.protocol": {"bench"},
    "hardware.emulators": {"bench", "model", "hardware.protocol"},
    "hardware": {"bench"},  # hardware/__init__.py
    "acquisition": {"bench", "hardware.protocol"},
    "validation": {"bench", "model", "acquisition"},
    "cli": {"bench", "model", "hardware", "hardware.protocol", "hardware.emulators", "acquisition",
            "validation"},
    # the pytest plugin: emulators, recorder and identification together, like the command line
    "testing": {"bench", "model", "hardware", "hardware.protocol", "hardware.emulators", "acquisition",
                "validation"},
}
# the one sanctioned exception: the simulated device of the sim backend runs in-process
EXCEPTIONS: dict[str, set[str]] = {"wearbench.acquisition.backends.sim": {"hardware.emulators"}}


def layer(module: str) -> str:
    """The layer of ``wearbench.X.Y...``: the package, or hardware's subpackage."""
    parts = module.split(".")
    if parts[1] == "hardware" and len(parts) > 2 and parts[2] in ("protocol", "emulators"):
        return f"hardware.{parts[2]}"
    return parts[1]


def library_modules() -> dict[str, Path]:
    """Every module of the installed package, by dotted name, from the folders pyproject maps."""
    modules = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            rel = path.relative_to(ROOT).with_suffix("")
            parts = list(rel.parts)
            if parts[-1] == "__init__":
                parts.pop()
            modules["wearbench." + ".".join(parts)] = path
    return modules


def imports(source: str, module: str, known: set[str]) -> set[str]:
    """The wearbench modules ``source`` (module ``module``) imports, anywhere in the file."""
    found = set()
    package = module if module + ".__init__" in known else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            # "from wearbench.model import simulate" imports the submodule when there is one
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        else:
            continue
        found |= {n for n in names if n.startswith("wearbench.") and n != module}
    return found


def graph() -> dict[str, set[str]]:
    modules = library_modules()
    known = set(modules) | {m + ".__init__" for m, p in modules.items() if p.name == "__init__.py"}
    edges = {}
    for module, path in modules.items():
        edges[module] = {_resolve(n, modules) for n in imports(path.read_text(encoding="utf-8"), module, known)}
    return edges


def _resolve(name: str, modules: dict[str, Path]) -> str:
    """The longest existing module prefix of ``name`` (``a.b.function`` -> ``a.b``)."""
    while name not in modules and "." in name:
        name = name.rpartition(".")[0]
    return name


def upward_edges(edges: dict[str, set[str]]) -> list[str]:
    bad = []
    for module, targets in edges.items():
        own = layer(module)
        allowed = ALLOWED[own] | {own} | EXCEPTIONS.get(module, set())
        bad += [f"{module} -> {t}" for t in sorted(targets) if layer(t) not in allowed]
    return bad


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), each a circle of imports.
    A package's ``__init__`` importing its own submodules is not counted (that is how packages
    expose a name; the submodules never need the package back)."""
    graph_ = {m: {t for t in ts if m != t.rpartition(".")[0]} for m, ts in edges.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph_.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph_):
        if v not in index:
            visit(v)
    return found


def test_every_layer_imports_only_the_layers_below_it():
    assert upward_edges(graph()) == []


def test_no_two_modules_import_each_other():
    assert cycles(graph()) == []


def test_no_library_module_starts_the_command_line_program():
    """Emulators and recorders start through functions; only ``wearbench.cli`` is the program."""
    offenders = [m for m, p in library_modules().items() if not m.startswith("wearbench.cli")
                 and ("wearbench.cli" in p.read_text(encoding="utf-8")
                      or '"wearbench", "emulate"' in p.read_text(encoding="utf-8"))]
    assert offenders == []


@pytest.mark.parametrize("module, source, expected", [
    ("wearbench.model.scene", "def f():\n    from wearbench.validation import report\n",
     ["wearbench.model.scene -> wearbench.validation.report"]),
    ("wearbench.bench.load", "import wearbench.model.kernel\n", ["wearbench.bench.load -> wearbench.model.kernel"]),
    ("wearbench.acquisition.recorder", "from wearbench.hardware.emulators import device\n",
     ["wearbench.acquisition.recorder -> wearbench.hardware.emulators.device"]),
    ("wearbench.acquisition.backends.sim", "from wearbench.hardware.emulators import device\n", []),
    ("wearbench.validation.compare", "from wearbench.model.simulation import simulate\n", []),
])
def test_the_check_catches_an_upward_import(module, source, expected):
    """The checker itself: an upward import written into a module is reported, an allowed one not."""
    modules = library_modules()
    known = set(modules) | {m + ".__init__" for m, p in modules.items() if p.name == "__init__.py"}
    edges = {module: {_resolve(n, modules) for n in imports(source, module, known)}}
    assert upward_edges(edges) == expected


def test_the_check_catches_a_circle():
    edges = {"wearbench.validation.a": {"wearbench.validation.b"}, "wearbench.validation.b": {"wearbench.validation.c"},
             "wearbench.validation.c": {"wearbench.validation.a"}, "wearbench.validation.d": {"wearbench.validation.a"}}
    assert cycles(edges) == [["wearbench.validation.a", "wearbench.validation.b", "wearbench.validation.c"]]
