"""The layers of wearbench point down: each package imports only the layers below it, and no two
modules import each other (directly or round a longer circle). Read from the source, every import
counted (also those inside functions and those named by a string to ``importlib.import_module``), so
a lazy import cannot hide an upward edge. The benchmarks are read too: they stand beside the command
line, may import every library layer, but not the program itself.

Three more rules keep the seams visible: no name with a leading underscore is imported or used
across modules (a name another file needs is public, documented and in its module's ``__all__``);
every import by a computed name (``importlib.import_module``) and every place that starts a process
is on an explicit list below, with the reason.

The rules are the docs' architecture page (docs/reference/architecture.md); this test is their owner.
"""

from __future__ import annotations

import ast
import functools
import itertools
from collections.abc import Set as AbstractSet
from pathlib import Path

import pytest

pytestmark = pytest.mark.no_kernels

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("bench", "model", "compute", "studies", "hardware", "acquisition", "validation", "reports", "synthetic",
            "testing", "cli", "wearbench")
LIBRARY = ("bench", "model", "compute", "studies", "hardware", "hardware.protocol", "hardware.emulators", "acquisition",
           "validation", "reports", "synthetic")

# layer -> the layers it may import (itself always allowed)
ALLOWED: dict[str, set[str]] = {
    "bench": set(),
    "model": {"bench"},
    "compute": {"bench", "model"},  # batches of simulations: its workers run the model
    "studies": {"bench", "model", "compute"},  # studies, sweeps and their figures
    "hardware.protocol": {"bench"},
    "hardware.emulators": {"bench", "model", "hardware.protocol"},
    "hardware": {"bench"},  # hardware/__init__.py
    "acquisition": {"bench", "hardware.protocol"},
    "validation": {"bench", "model", "compute", "acquisition"},
    "reports": {"bench", "model", "compute", "acquisition", "validation"},  # figures and HTML of validation's results
    # truths and lives of known truth: emulators, recorder and validation together
    "synthetic": {"bench", "model", "compute", "hardware", "hardware.protocol", "hardware.emulators", "acquisition",
                  "validation"},
    # the pytest plugin: emulated benches, recorder and identification together
    "testing": set(LIBRARY),
    "api": set(LIBRARY),  # the public face, ``import wearbench``
    "cli": set(LIBRARY) | {"testing", "api"},
    "benchmarks": set(LIBRARY) | {"testing", "api"},  # scripts beside the program: not the program itself
}
# inside validation, the job groups point down too: measurement < inference < estimation < comparison < workflows
VALIDATION_FLOORS = ("measurement", "inference", "estimation", "comparison", "workflows")
# the one sanctioned exception: the simulated device of the sim backend runs in-process
EXCEPTIONS: dict[str, set[str]] = {"wearbench.acquisition.backends.sim": {"hardware.emulators"}}


def layer(module: str) -> str:
    """The layer of ``wearbench.X.Y...``: the package, or hardware's subpackage (``benchmarks.X``:
    the benchmarks)."""
    parts = module.split(".")
    if parts[0] == "benchmarks":
        return "benchmarks"
    if module == "wearbench":
        return "api"
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
            modules[".".join(["wearbench", *parts[parts[0] == "wearbench":]])] = path
    return modules


def _import_nodes(tree: ast.Module):
    """Every import statement and ``import_module("...")`` call of a module, with whether it runs
    when the module is imported (at module level, not inside a function)."""
    lazy: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            lazy |= {id(n) for n in ast.walk(node) if n is not node}
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)) or _imported_by_name(node) is not None:
            yield node, id(node) not in lazy


def _imported_by_name(node: ast.AST) -> str | None:
    """The module a call ``importlib.import_module(NAME)`` (or ``__import__``) names: the string, or
    the literal head of an f-string (``f"wearbench.model.{name}"`` -> ``wearbench.model``)."""
    if not (isinstance(node, ast.Call) and node.args):
        return None
    func = node.func
    name = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""
    if name not in ("import_module", "__import__"):
        return None
    arg = node.args[0]
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return arg.value
    if isinstance(arg, ast.JoinedStr) and arg.values and isinstance(arg.values[0], ast.Constant):
        return str(arg.values[0].value).rstrip(".")
    return None


def imports(source: str, module: str, known: AbstractSet[str], *, eager_only: bool = False) -> set[str]:
    """The wearbench modules ``source`` (module ``module``) imports, anywhere in the file (with
    ``eager_only``, only those imported when the module itself is)."""
    found = set()
    package = module if module + ".__init__" in known else module.rpartition(".")[0]
    for node, eager in _import_nodes(ast.parse(source)):
        if eager_only and not eager:
            continue
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
            names = [_imported_by_name(node)]
        found |= {n for n in names if n.startswith("wearbench.") and n != module}
    return found


def graph(sources: dict[str, str] | None = None) -> dict[str, set[str]]:
    """Import edges between the library's modules and the benchmarks (``sources``: module -> source
    in place of the files, for the checker's own tests). A package's ``__init__`` keeps its edges to
    its own submodules only where it imports them eagerly: a lazy face is no circle, an eager one
    that a submodule imports back is one (it fails on import)."""
    _, _, texts = _tree()
    return {module: set(_edges(module, text)) for module, text in {**texts, **(sources or {})}.items()}


@functools.cache
def _tree() -> tuple[dict[str, Path], frozenset[str], dict[str, str]]:
    """The library's modules, their names with packages' ``__init__``, and the texts of those and the
    benchmarks (:func:`_sources`'s, read once per test session)."""
    modules = library_modules()
    known = frozenset(modules) | {m + ".__init__" for m, p in modules.items() if p.name == "__init__.py"}
    return modules, known, _sources()[0]


@functools.cache
def _edges(module: str, text: str) -> frozenset[str]:
    """The modules that ``text``, as module ``module``, has import edges to (see :func:`graph`)."""
    modules, known, _ = _tree()
    targets = {_resolve(n, modules) for n in imports(text, module, known)}
    if module + ".__init__" in known:
        eager = {_resolve(n, modules) for n in imports(text, module, known, eager_only=True)}
        targets = {t for t in targets if t.rpartition(".")[0] != module or t in eager}
    return frozenset(targets)


def benchmark_scripts() -> dict[str, Path]:
    """The benchmarks, by module name (``benchmarks.validation.identify``; a package's ``__init__`` by
    the package's name)."""
    out = {}
    for p in sorted((ROOT / "benchmarks").rglob("*.py")):
        parts = list(p.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = p
    return out


def _resolve(name: str, modules: dict[str, Path]) -> str:
    """The longest existing module prefix of ``name`` (``a.b.function`` -> ``a.b``)."""
    while name not in modules and "." in name:
        name = name.rpartition(".")[0]
    return name


def validation_floor(module: str) -> int | None:
    """The floor of a module of validation's job groups (``VALIDATION_FLOORS``); None elsewhere."""
    parts = module.split(".")
    if parts[:2] == ["wearbench", "validation"] and len(parts) > 2 and parts[2] in VALIDATION_FLOORS:
        return VALIDATION_FLOORS.index(parts[2])
    return None


def upward_edges(edges: dict[str, set[str]]) -> list[str]:
    bad = []
    for module, targets in edges.items():
        own = layer(module)
        allowed = ALLOWED[own] | {own} | EXCEPTIONS.get(module, set())
        floor = validation_floor(module)
        bad += [f"{module} -> {t}" for t in sorted(targets) if layer(t) not in allowed
                or floor is not None and (validation_floor(t) or 0) > floor]
    return bad


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), each a circle of imports."""
    graph_ = edges
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


_LAUNCHERS = {"system", "popen", "run", "Popen", "call", "check_call", "check_output", "create_subprocess_shell",
              "create_subprocess_exec", "spawnlp", "execlp", "execvp"}


def launches_program(source: str) -> bool:
    """Whether ``source`` starts the ``wearbench`` program: names ``wearbench.cli`` (an import or
    ``-m wearbench.cli``) or builds a command line whose program is ``wearbench``
    (``["wearbench", "record", ...]``, ``("wearbench", ...)``, ``shutil.which("wearbench")``)."""
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value.startswith("wearbench.cli"):
            return True
        if (isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", "")) in _LAUNCHERS
                and any(isinstance(a, ast.Constant) and str(a.value).split()[:1] == ["wearbench"] for a in node.args)):
            return True  # a shell command line: os.system("wearbench emulate ...")
        if isinstance(node, (ast.List, ast.Tuple)) and node.elts:
            first = node.elts[0]
            second = node.elts[1] if len(node.elts) > 1 else None
            if (isinstance(first, ast.Constant) and first.value in ("wearbench", "wearbench.cli")
                    and (isinstance(second, ast.Starred) or isinstance(second, ast.Constant)
                         and isinstance(second.value, str))):
                return True
            heads = [e.value for e in node.elts if isinstance(e, ast.Constant)]
            if any(a == "-m" and b in ("wearbench", "wearbench.cli") for a, b in itertools.pairwise(heads)):
                return True
        if isinstance(node, ast.Call) and any(isinstance(a, ast.Constant) and a.value == "wearbench"
                                              for a in node.args) and getattr(node.func, "attr", "") == "which":
            return True
    return False


def test_no_library_module_starts_the_command_line_program():
    """Emulators and recorders start through functions; only ``wearbench.cli`` is the program."""
    texts, _ = _sources()
    offenders = [m for m, t in texts.items() if not m.startswith("wearbench.cli") and launches_program(t)]
    assert offenders == []


@pytest.mark.parametrize("source, launches", [
    ("subprocess.run(['wearbench', 'record', 'b.toml'])\n", True),
    ("subprocess.Popen((sys.executable, '-m', 'wearbench.cli', 'emulate'))\n", True),
    ("cmd = [shutil.which('wearbench'), 'emulate']\n", True),
    ("os.system('wearbench emulate b.toml --serial')\n", True),
    ("name = 'wearbench'\nlibrary = ('wearbench', 2)\n", False),
    ("writer.start(profile='x', library='wearbench')\n", False),
])
def test_the_check_catches_a_program_launch(source, launches):
    assert launches_program(source) is launches


@pytest.mark.parametrize("module, source, expected", [
    ("wearbench.model.scene", "def f():\n    from wearbench.reports import comparison\n",
     ["wearbench.model.scene -> wearbench.reports.comparison"]),
    ("wearbench.validation.measurement.tap_test", "from wearbench.validation.workflows.assess import stream_start\n",
     ["wearbench.validation.measurement.tap_test -> wearbench.validation.workflows.assess"]),
    ("wearbench.validation.workflows.assess", "from wearbench.validation.measurement.session import load_session\n",
     []),
    ("wearbench.validation.estimation.track", "def f():\n    from wearbench.reports.track import track_figure\n",
     ["wearbench.validation.estimation.track -> wearbench.reports.track"]),
    ("wearbench.bench.load", "import wearbench.model.kernel\n", ["wearbench.bench.load -> wearbench.model.kernel"]),
    ("wearbench.acquisition.recorder", "from wearbench.hardware.emulators import device\n",
     ["wearbench.acquisition.recorder -> wearbench.hardware.emulators.device"]),
    ("wearbench.acquisition.backends.sim", "from wearbench.hardware.emulators import device\n", []),
    ("wearbench.validation.comparison.compare", "from wearbench.model.simulation import simulate\n", []),
    ("wearbench.model.scene", "importlib.import_module('wearbench.reports.comparison')\n",
     ["wearbench.model.scene -> wearbench.reports.comparison"]),
    ("wearbench.bench.load", "def f(n):\n    return importlib.import_module(f'wearbench.acquisition.{n}')\n",
     ["wearbench.bench.load -> wearbench.acquisition"]),
    ("benchmarks.identify", "from wearbench.cli.demo import record_state\n",
     ["benchmarks.identify -> wearbench.cli.demo"]),
    ("benchmarks.identify", "from wearbench.validation.inference.identify import fit_states\n", []),
])
def test_the_check_catches_an_upward_import(module, source, expected):
    """The checker itself: an upward import written into a module is reported, an allowed one not."""
    edges = graph({module: source})
    assert upward_edges({module: edges[module]}) == expected


def test_the_check_catches_a_circle():
    edges = {"wearbench.validation.a": {"wearbench.validation.b"}, "wearbench.validation.b": {"wearbench.validation.c"},
             "wearbench.validation.c": {"wearbench.validation.a"}, "wearbench.validation.d": {"wearbench.validation.a"}}
    assert cycles(edges) == [["wearbench.validation.a", "wearbench.validation.b", "wearbench.validation.c"]]


@pytest.mark.parametrize("init_source, circle", [
    ("from wearbench.validation.comparison.compare import compare_session\n", True),   # eager: compare needs it back
    ("def __getattr__(name):\n    from wearbench.validation import compare\n", False),  # a lazy face
])
def test_the_check_catches_a_circle_through_a_package_init(init_source, circle):
    """A submodule importing a name its package's ``__init__`` defines, while that ``__init__``
    imports the submodule at import time, crashes on import: that circle is found; a lazy face is not one."""
    edges = graph({"wearbench.validation": init_source,
                   "wearbench.validation.comparison.compare": "from wearbench.validation import CompareOptions\n"})
    found = [c for c in cycles(edges) if "wearbench.validation" in c]
    assert bool(found) is circle


# ---- public seams ----------------------------------------------------------------------------------

# module -> why it imports by a computed name (the call sites allowed; any other is a failure)
DYNAMIC_IMPORTS: dict[str, str] = {
    "wearbench": "the public face: names load with their module on first use",
    "wearbench.validation": "a lazy face over its job groups",
    "wearbench.testing": "a lazy face: the pytest plugin loads the acquisition stack only when a test uses it",
    "wearbench.cli": "one module per subcommand, imported by name so --help stays fast",
    "wearbench.acquisition.backends": "the backend registry: a backend's module by its name in the bench file",
}
# module -> the processes it starts (any other module starting one is a failure)
PROCESS_LAUNCHES: dict[str, str] = {
    "wearbench.compute.cluster": "the Dask LocalCluster's worker processes",
    "wearbench.hardware.emulators.serial_server": "the serial emulator in its own process (forkserver)",
    "wearbench.testing.mcap_readers": "npm and node: the reader Foxglove uses, checking the files we write",
    "benchmarks.compute.blas_threads": "fresh interpreters, one per BLAS setting, alone and two at once",
    "benchmarks.compute.scale_out": "a process pool timed against the cluster",
    "benchmarks.compute.suite_durations": "pytest on the suite, timed as CI runs it",
    "benchmarks.model.trajectory_identity": "a fresh interpreter per model source, for bit identity",
    "benchmarks.model.profile_revolution": "a fresh interpreter, so compilation is not timed",
    "benchmarks.result_json": "git, for the commit a result was measured on",
}
# module -> its calls that start a process
_PROCESS_CALLS = {
    "subprocess": {"run", "Popen", "call", "check_call", "check_output"},
    "os": {"system", "popen", "spawnl", "spawnlp", "spawnv", "spawnvp", "execl", "execlp", "execv", "execvp"},
    "asyncio": {"create_subprocess_exec", "create_subprocess_shell"},
    "multiprocessing": {"get_context", "Process", "Pool"},
}


def _wearbench_aliases(tree: ast.Module, module: str, known: AbstractSet[str]) -> dict[str, str]:
    """Local names bound to wearbench modules by ``import`` / ``from ... import module``."""
    package = module if module + ".__init__" in known else module.rpartition(".")[0]
    aliases = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith(("wearbench.", "benchmarks.")):
                    aliases[a.asname or a.name.split(".")[0]] = a.name if a.asname else a.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                base = ".".join(anchor[: len(anchor) - (node.level - 1)] + ([base] if base else []))
            for a in node.names:
                if f"{base}.{a.name}" in known:
                    aliases[a.asname or a.name] = f"{base}.{a.name}"
    return aliases


def private_crossings(source: str, module: str, known: AbstractSet[str]) -> list[str]:
    """Names with one leading underscore that ``source`` (module ``module``) imports from, or reads
    off, another wearbench module: ``module -> other._name``."""
    tree = ast.parse(source)
    package = module if module + ".__init__" in known else module.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                base = ".".join(anchor[: len(anchor) - (node.level - 1)] + ([base] if base else []))
            if base.startswith(("wearbench", "benchmarks")) and base != module:
                found += [f"{module} -> {base}.{a.name}" for a in node.names
                          if a.name.startswith("_") and not a.name.startswith("__")]
    aliases = _wearbench_aliases(tree, module, known)
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")
                and isinstance(node.value, ast.Name) and node.value.id in aliases
                and aliases[node.value.id] != module):
            found.append(f"{module} -> {aliases[node.value.id]}.{node.attr}")
    return sorted(set(found))


def dynamic_imports(source: str) -> int:
    """How many calls of ``source`` import a module by a computed name (``import_module``, ``__import__``)."""
    return sum(1 for node in ast.walk(ast.parse(source)) if isinstance(node, ast.Call)
               and (getattr(node.func, "attr", None) or getattr(node.func, "id", None)) in ("import_module", "__import__"))


def starts_processes(source: str) -> bool:
    """Whether ``source`` starts a process: ``subprocess``/``os``/``asyncio``/``multiprocessing`` calls that
    launch one, a multiprocessing context's ``Process``/``Pool``, or a Dask ``LocalCluster``."""
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        if isinstance(func, ast.Name) and func.id in ("Popen", "LocalCluster"):
            return True
        if isinstance(func, ast.Attribute):
            base = func.value
            while isinstance(base, ast.Attribute):
                base = base.value
            if isinstance(base, ast.Name) and func.attr in _PROCESS_CALLS.get(base.id, ()):
                return True
            if func.attr in ("Process", "Pool") and isinstance(func.value, ast.Name) and "context" in func.value.id:
                return True
    return False


@functools.cache
def _sources() -> tuple[dict[str, str], frozenset[str]]:
    """The texts of the library's modules and the benchmarks, and their names with packages'
    ``__init__``: read once per test session (the files do not change while it runs)."""
    modules = {**library_modules(), **benchmark_scripts()}
    known = frozenset(modules) | {m + ".__init__" for m, p in modules.items() if p.name == "__init__.py"}
    texts = {m: p.read_text(encoding="utf-8") for m, p in modules.items()}
    return texts, known


def test_no_private_name_crosses_a_module():
    texts, known = _sources()
    assert [c for m, t in texts.items() for c in private_crossings(t, m, known)] == []


def test_imports_by_computed_name_are_the_listed_ones():
    texts, _ = _sources()
    assert sorted(m for m, t in texts.items() if dynamic_imports(t)) == sorted(DYNAMIC_IMPORTS)


def test_processes_start_only_where_listed():
    texts, _ = _sources()
    assert sorted(m for m, t in texts.items() if starts_processes(t)) == sorted(PROCESS_LAUNCHES)


@pytest.mark.parametrize("module, source, expected", [
    ("wearbench.validation.estimation.track", "from wearbench.validation.estimation.estimate import _interval\n",
     ["wearbench.validation.estimation.track -> wearbench.validation.estimation.estimate._interval"]),
    ("benchmarks.profile", "import wearbench.model.kernel as K\nK._schur(1)\n",
     ["benchmarks.profile -> wearbench.model.kernel._schur"]),
    ("benchmarks.acquisition.live_view", "from benchmarks.acquisition.record_throughput import _metered\n",
     ["benchmarks.acquisition.live_view -> benchmarks.acquisition.record_throughput._metered"]),
    ("wearbench.validation.estimation.track", "from wearbench.validation.estimation import estimate\nestimate._x\n",
     ["wearbench.validation.estimation.track -> wearbench.validation.estimation.estimate._x"]),
    ("wearbench.validation.estimation.track", "from wearbench.validation.estimation.estimate import Interval\n", []),
    ("wearbench.validation.estimation.track", "def _own():\n    pass\n_own()\nx.__class__\n", []),
])
def test_the_check_catches_a_private_name_crossing(module, source, expected):
    _, known = _sources()
    assert private_crossings(source, module, known) == expected


@pytest.mark.parametrize("source, count", [
    ("import importlib\nimportlib.import_module(name)\n", 1),
    ("from importlib import import_module\nimport_module(f'wearbench.{x}')\n", 1),
    ("__import__(name)\n", 1),
    ("import importlib\nimportlib.reload(m)\n", 0),
])
def test_the_check_catches_an_import_by_computed_name(source, count):
    assert dynamic_imports(source) == count


@pytest.mark.parametrize("source, launches", [
    ("import subprocess\nsubprocess.run(['node', 'x.mjs'])\n", True),
    ("import os\nos.system('ls')\n", True),
    ("import multiprocessing\nctx = multiprocessing.get_context('spawn')\n", True),
    ("context.Process(target=f).start()\n", True),
    ("from distributed import LocalCluster\nLocalCluster(n_workers=2)\n", True),
    ("recorder.run()\nos.path.join('a', 'b')\nasyncio.run(main())\n", False),
])
def test_the_check_catches_a_process_launch(source, launches):
    assert starts_processes(source) is launches
