"""The layout keeps its promises: one home per system, no import cycles, no work at import time,
library hygiene.  Oracles: the package's own source files (read as text and syntax trees) and a
fresh interpreter's audit events."""
from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:          # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = {"descent_fmus.models": ROOT / "models", "descent_fmus.synthesis": ROOT / "synthesis"}


def _modules():
    """{module name: path} of every module of the two packages."""
    out = {}
    for pkg, base in PACKAGES.items():
        for path in base.rglob("*.py"):
            rel = path.relative_to(base).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            out[".".join([pkg, *parts])] = path
    return out


def _imports(path: Path, name: str, modules) -> set:
    """descent_fmus modules imported anywhere in ``path`` (module level and inside functions)."""
    found = set()
    pkg = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = pkg.split(".")
                base = ".".join(parent[:len(parent) - node.level + 1] + ([base] if base else []))
            for alias in node.names:
                full = f"{base}.{alias.name}"
                found.add(full if full in modules else base)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
    return {m for m in found if m in modules and m != name}


def test_no_import_cycle():
    modules = _modules()
    graph = {m: _imports(p, m, modules) for m, p in modules.items()}
    # a package importing its own sub-modules (its SYSTEM record) is not a cycle to report
    graph = {m: {d for d in deps if not d.startswith(m + ".")} for m, deps in graph.items()}
    state, stack = {}, []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for d in sorted(graph[m]):
            if state.get(d) == 1:
                raise AssertionError("import cycle: " + " -> ".join(stack[stack.index(d):] + [d]))
            if d not in state:
                visit(d)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)


def _node(name: str, path: Path) -> str:
    """The package a module belongs to (a package's ``__init__``: the package itself); the
    top-level modules of ``synthesis/`` and ``models/`` (``registry``, ``paths``, ...) are
    nodes of their own."""
    pkg = name if path.name == "__init__.py" else name.rpartition(".")[0]
    return name if pkg in PACKAGES and path.name != "__init__.py" else pkg


def package_cycles() -> list:
    """Import cycles between packages (each as a list of package names, the first repeated at
    the end).  A package's ``__init__`` importing its own sub-packages (its SYSTEM record) is
    no cycle; any other module importing its parent's package and back is."""
    modules = _modules()
    graph: dict = {}
    for name, path in modules.items():
        a = _node(name, path)
        for dep in _imports(path, name, modules):
            b = _node(dep, modules[dep])
            if a != b and not (path.name == "__init__.py" and b.startswith(a + ".")):
                graph.setdefault(a, set()).add(b)
    state, stack, cycles = {}, [], []

    def visit(n):
        state[n] = 1
        stack.append(n)
        for d in sorted(graph.get(n, ())):
            if state.get(d) == 1:
                cycles.append(stack[stack.index(d):] + [d])
            elif d not in state:
                visit(d)
        stack.pop()
        state[n] = 2

    for n in sorted(graph):
        if n not in state:
            visit(n)
    return cycles


def test_no_import_cycle_between_packages():
    # e.g. synthesis.fmi.native importing synthesis.fmi (units) while synthesis.fmi imports
    # synthesis.fmi.native (the compiler) was one
    assert package_cycles() == []


def test_models_depend_on_nothing_above_them():
    for name, path in _modules().items():
        if name.startswith("descent_fmus.models"):
            assert "descent_fmus.synthesis" not in path.read_text(), path


AUDIT = r"""
import sys
opened = []
def hook(event, args):
    if event == "open" and isinstance(args[0], str):
        opened.append(args[0])
sys.addaudithook(hook)
import descent_fmus.synthesis
from descent_fmus.synthesis.cli.main import build_parser
build_parser()                               # imports every system package and its commands
from descent_fmus.synthesis.registry import all_systems, problem_names
all_systems(); problem_names()
data = [p for p in opened if p.endswith((".json", ".toml", ".csv", ".fmu", ".npz", ".png"))]
print("DATA", data)
print("SOLVERS", sorted(m for m in ("scipy.integrate", "scipy.optimize", "matplotlib.pyplot")
                        if m in sys.modules))
"""


def test_importing_the_package_reads_no_data_and_runs_no_solver():
    # every system registered, every command parser built: still no data file read and no
    # solver module imported (the systems keep expensive work in functions called on demand)
    r = subprocess.run([sys.executable, "-c", AUDIT], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    lines = dict(line.split(" ", 1) for line in r.stdout.splitlines())
    assert lines["DATA"] == "[]", lines["DATA"]
    assert lines["SOLVERS"] == "[]", lines["SOLVERS"]


def test_every_c_file_ships_as_package_data():
    # the hand-written C of the native FMUs (the core's and a system's) is installed with the
    # package: every .c/.h file under synthesis/ matches a package-data glob of its package
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    globs = data["package-data"]
    missing = []
    for path in sorted((ROOT / "synthesis").rglob("*.[ch]")):
        pkg_dir = next(p for p in path.parents if (p / "__init__.py").is_file())
        pkg = "descent_fmus." + ".".join(pkg_dir.relative_to(ROOT).parts)
        rel = path.relative_to(pkg_dir)
        if not any(rel.match(g) and len(rel.parts) == len(Path(g).parts)
                   for g in globs.get(pkg, ()) + globs.get("*", [])):
            missing.append(str(path.relative_to(ROOT)))
    assert not missing, f"not in [tool.setuptools.package-data]: {missing}"


def test_every_package_is_installed():
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
                 ["packages"])
    on_disk = {n for n, p in _modules().items() if p.name == "__init__.py"}
    assert on_disk == listed, f"pyproject.toml lists {sorted(listed ^ on_disk)} wrongly"


def test_every_system_has_one_home():
    from descent_fmus.synthesis.registry import SYSTEMS, get_system
    assert sorted(p.name for p in (ROOT / "synthesis/systems").iterdir()
                  if (p / "__init__.py").is_file()) == sorted(SYSTEMS)
    for stem in SYSTEMS:
        system = get_system(stem)
        assert system.stem == stem
        assert (ROOT / "models" / f"{stem}.py").is_file()
        assert list((ROOT / "tests" / "systems" / stem).glob(f"test_{stem}_*.py")), stem
        for spec in system.fmus:
            module = spec.split(":")[0]
            assert (ROOT / "models" / (module.replace(".", "/") + ".py")).is_file(), spec


#: Test folders named after something other than a folder of synthesis/ (what they test).
TESTED_ELSEWHERE = {"docs": "docs", "suite": "benchmarks/suite"}


def test_tests_are_laid_out_like_the_code():
    # a test file sits in the folder of what it tests: tests/<path>/ mirrors synthesis/<path>/
    # (tests/fmi/native/, tests/systems/<stem>/, ...) or a folder of TESTED_ELSEWHERE; at the top
    # only this file (the whole repository's layout); names unique (pytest's import by name)
    tests = ROOT / "tests"
    assert [p.name for p in tests.glob("test_*.py")] == ["test_layout.py"]
    files = sorted(tests.rglob("test_*.py"))
    names = [p.name for p in files]
    assert len(names) == len(set(names)), sorted(n for n in names if names.count(n) > 1)
    for path in files:
        rel = path.parent.relative_to(tests).parts
        if rel:
            code = ROOT / TESTED_ELSEWHERE.get(rel[0], f"synthesis/{rel[0]}") / Path(*rel[1:])
            assert code.is_dir(), f"{path.relative_to(ROOT)}: no folder {code.relative_to(ROOT)}"


OUTSIDE = re.compile(r"SPEC\b|DESIGN\.md|\bissue \d|\b[Ss]eed 00\d|shared/")


@pytest.mark.parametrize("folder", ["models", "synthesis", "tests", "benchmarks", "docs"])
def test_no_pointer_outside_the_repository(folder):
    bad = []
    for path in (ROOT / folder).rglob("*.py"):
        for k, line in enumerate(path.read_text().splitlines(), 1):
            if OUTSIDE.search(line) and "OUTSIDE = re.compile" not in line:
                bad.append(f"{path.relative_to(ROOT)}:{k}: {line.strip()}")
    assert not bad, "\n".join(bad)


def test_library_code_never_chooses_the_matplotlib_backend():
    for folder in ("models", "synthesis"):
        for path in (ROOT / folder).rglob("*.py"):
            assert "matplotlib.use(" not in path.read_text(), path


# -- the core grouped by job, small modules and functions -----------------------------------------
#: The folders of synthesis/ and what each may import from the package (a layer imports only
#: the layers below it).  models/ is the ground floor; fmi/ knows FMUs, not problems; problems/
#: knows the FMI layer and the methods' types; run/ flies problems with methods; cli/ and the
#: systems sit on top.
LAYERS = {
    "methods": {"models", "methods"},
    "fmi": {"models", "methods", "fmi", "paths", "plotting"},
    "problems": {"models", "methods", "fmi", "problems", "paths"},
    "run": {"models", "methods", "fmi", "problems", "run", "paths", "plotting"},
}


def _layer(module: str) -> str:
    parts = module.split(".")
    if parts[1] == "models":
        return "models"
    return parts[2] if len(parts) > 2 else "synthesis"


def test_synthesis_top_level_is_a_handful_of_modules_and_job_folders():
    top = sorted(p.stem for p in (ROOT / "synthesis").glob("*.py"))
    assert top == ["__init__", "paths", "plotting", "registry"], top
    folders = sorted(p.name for p in (ROOT / "synthesis").iterdir()
                     if (p / "__init__.py").is_file())
    assert folders == ["cli", "fmi", "methods", "problems", "run", "systems"], folders


def test_each_job_folder_imports_only_the_layers_below_it():
    modules = _modules()
    bad = []
    for name, path in modules.items():
        layer = _layer(name)
        if layer not in LAYERS:
            continue
        for dep in _imports(path, name, modules):
            dep_layer = _layer(dep)
            if dep_layer not in LAYERS[layer] and dep_layer != "synthesis":
                bad.append(f"{name} imports {dep}")
            elif dep_layer == "synthesis" and dep.rsplit(".", 1)[-1] not in LAYERS[layer]:
                bad.append(f"{name} imports {dep}")
    assert not bad, "\n".join(bad)


def test_methods_know_no_system():
    # the general methods hold no system's numbers: no import of a system or of a plant model
    # (only the network-operator operation table, the fixed-step integrators and RK4 helpers)
    allowed = {"descent_fmus.models.controllers.network_operator",
               "descent_fmus.models.controllers.operation_table",
               "descent_fmus.models.controllers.law_interpreter",
               "descent_fmus.models.integrators", "descent_fmus.models.rk4_input"}
    modules = _modules()
    for name, path in modules.items():
        if ".synthesis.methods." in name:
            deps = {d for d in _imports(path, name, modules) if d.startswith("descent_fmus.models")}
            assert deps <= allowed, (name, deps - allowed)


#: The model modules every system shares: the core may import these, and no other model (a
#: system's plant or its own controllers).
SHARED_MODELS = {"descent_fmus.models", "descent_fmus.models.controllers",
                 *(f"descent_fmus.models.{m}" for m in (
                     "params", "integrators", "fmu_support", "pythonfmu_compat", "rk4_input",
                     "traceable", "controllers.network_operator", "controllers.operation_table",
                     "controllers.law_interpreter", "controllers.program_table"))}
CORE = ("fmi", "run", "methods", "problems", "cli")


def core_imports_of_systems() -> list:
    """``"module imports dependency"`` for every import of a system (``synthesis.systems.*``)
    or of a system's model (``models.reentry``, ``models.controllers.drag_estimator``, ...) by
    the core (:data:`CORE`)."""
    modules = _modules()
    bad = []
    for name, path in modules.items():
        if _layer(name) not in CORE:
            continue
        for dep in _imports(path, name, modules):
            if dep.startswith("descent_fmus.synthesis.systems") or (
                    dep.startswith("descent_fmus.models") and dep not in SHARED_MODELS):
                bad.append(f"{name} imports {dep}")
    return bad


def test_the_core_knows_no_system():
    # fmi, run, methods, problems and cli find the systems only through the registry: no import
    # of a system's package or of a system's models (S1's native code lives in its package)
    assert core_imports_of_systems() == []


#: Folders whose modules pass the module gates (a docstring naming the job, at most 500 lines):
#: the package and the benchmark scripts.  The function gate (80 lines) covers the package.
MODULE_GATE = ("models", "synthesis", "benchmarks")


def test_every_module_names_its_job():
    # every module starts with a docstring whose first line says what the module is for
    bad = []
    for folder in MODULE_GATE:
        for path in (ROOT / folder).rglob("*.py"):
            doc = ast.get_docstring(ast.parse(path.read_text()))
            if not doc or len(doc.splitlines()[0].split()) < 3:
                bad.append(str(path.relative_to(ROOT)))
    assert not bad, f"modules without a docstring naming their job: {bad}"


#: Functions allowed beyond 80 lines: none today (a table, such as an operation list, would be
#: named here with its reason).
LONG_FUNCTIONS: dict = {}


def test_no_module_over_500_lines_and_no_function_over_80():
    long_modules, long_functions = [], []
    for folder in MODULE_GATE:
        for path in (ROOT / folder).rglob("*.py"):
            text = path.read_text()
            n = len(text.splitlines())
            if n > 500:
                long_modules.append(f"{path.relative_to(ROOT)}: {n} lines")
            if folder == "benchmarks":
                continue
            for node in ast.walk(ast.parse(text)):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    size = node.end_lineno - node.lineno + 1
                    key = f"{path.relative_to(ROOT)}:{node.name}"
                    if size > 80 and key not in LONG_FUNCTIONS:
                        long_functions.append(f"{key}: {size} lines")
    assert not long_modules, long_modules
    assert not long_functions, long_functions
