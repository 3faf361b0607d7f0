"""The shape of the code: imports only look down (no cycle in pumpsim/ or codegen/, counting every
import statement, those inside functions too), the bottom layer loads no kernel, and the size and
privacy rules of the layered design (docs: the explanation of the layers)."""
import ast
import json
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
# codegen/ is installed as pumpsim.codegen (a checkout maps the name to its folder)
PACKAGES = {"pumpsim": ROOT / "pumpsim", "pumpsim.codegen": ROOT / "codegen"}
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 60
# what the bottom layer must not load: compiled kernels, CasADi, simulation and the checks above it
ABOVE_THE_BOTTOM = ("casadi", "pumpsim.kernels", "pumpsim.simulate", "pumpsim.constrained",
                    "pumpsim.contact", "pumpsim.geometry", "pumpsim.plausibility", "pumpsim.checks",
                    "pumpsim.codegen", "pumpsim.pneumatics.simulate", "pumpsim.pneumatics.run")


def source_modules() -> dict:
    """Module name -> source file, for every .py file of pumpsim/ and codegen/."""
    mods = {}
    for package, folder in PACKAGES.items():
        for path in folder.rglob("*.py"):
            parts = list(path.relative_to(folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            mods[".".join([package, *parts])] = path
    return mods


def _targets(module: str, path: Path, node, mods: dict) -> list:
    """The modules of `mods` one import statement of `module` names (relative forms resolved;
    `from package import name` is the submodule when `name` is one, else the package)."""
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names]
    else:
        base = node.module or ""
        if node.level:
            package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
            package = package[:len(package) - node.level + 1]
            base = ".".join(package + ([base] if base else []))
        names = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
    out = []
    for name in names:
        if name == "codegen" or name.startswith("codegen."):  # never installed at top level
            name = "pumpsim." + name
        while name and name not in mods:
            name = name.rpartition(".")[0]
        if name:
            out.append(name)
    return out


def import_graph() -> dict:
    """module -> the modules it imports, from every import statement (ast.walk: module level, in
    functions, in classes, under `if`). A package importing its own submodules (its interface)
    and a submodule naming its own package are the import system's normal shape, not edges."""
    mods = source_modules()
    graph = defaultdict(set)
    for module, path in mods.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                for target in _targets(module, path, node, mods):
                    if target != module and not target.startswith(module + ".") \
                            and not module.startswith(target + "."):
                        graph[module].add(target)
    return {m: graph.get(m, set()) for m in mods}


def cycles(graph: dict) -> list:
    """Per strongly connected component of more than one module: (one import cycle through it, a
    list of modules with first = last; every module of the component, sorted)."""
    index, low, stack, on_stack, components = {}, {}, [], set(), []

    def visit(v):  # Tarjan; the graph has ~150 nodes, recursion is fine
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                components.append(comp)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return [(_cycle_through(comp, graph), sorted(comp)) for comp in components]


def _cycle_through(comp: set, graph: dict) -> list:
    """A shortest path from the component's first module back to itself (breadth first)."""
    start = min(comp)
    previous, frontier = {start: None}, [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph[v] & comp):
                if w == start:
                    path = [v]
                    while previous[path[-1]] is not None:
                        path.append(previous[path[-1]])
                    return [start, *reversed(path[:-1]), start] if len(path) > 1 else [start, v, start]
                if w not in previous:
                    previous[w] = v
                    nxt.append(w)
        frontier = nxt
    return sorted(comp)


def test_graph_sees_imports_inside_functions_and_relative_forms():
    """The graph builder itself: a lazy import inside a function and `from . import x` count."""
    graph = import_graph()
    assert "pumpsim.codegen.build" in graph["pumpsim.kernels.cache"]  # inside build_library
    assert "pumpsim.interrupt" in graph["pumpsim.contact"]  # from . import interrupt
    assert "pumpsim.codegen.install" in graph["pumpsim.codegen.simd"]  # from .install import ...
    made_up = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycles(made_up) == [(["a", "b", "c", "a"], ["a", "b", "c"])]


def test_no_import_cycle():
    found = cycles(import_graph())
    assert not found, "import cycles (every import statement counted):\n" + "\n".join(
        f"{' -> '.join(path)}  (the cycle's modules: {', '.join(comp)})" for path, comp in found)


def _modules_after(code: str) -> list:
    """sys.modules after running `code` in a fresh interpreter (this checkout first on the path)."""
    script = f"import sys\nsys.path.insert(0, {str(ROOT)!r})\n{code}\nimport json\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("module", ["pumpsim.config", "pumpsim.data", "pumpsim.model_spec"])
def test_the_bottom_layer_loads_no_kernel(module):
    loaded = _modules_after(f"import {module}")
    assert module in loaded
    above = [m for m in loaded if m.startswith(ABOVE_THE_BOTTOM)]
    assert above == [], f"import {module} loaded {above}"


def test_import_pumpsim_stays_light():
    """The public names load on first use: the package alone imports none of its modules."""
    loaded = _modules_after("import pumpsim")
    assert [m for m in loaded if m.startswith("pumpsim.")] == []
    assert [m for m in loaded if m.split(".")[0] in ("numpy", "scipy", "casadi")] == []


def test_loading_a_config_does_not_check_the_geometry_but_the_api_does(tmp_path):
    """The layer split: load_config parses, checked_config (the public pumpsim.load_config) checks."""
    import pumpsim
    from pumpsim.checks import checked_config
    from pumpsim.config import load_config
    from pumpsim.errors import ConfigError

    text = (ROOT / "examples" / "test_rig.toml").read_text(encoding="utf-8")
    assert "length = 0.012" in text
    bad = tmp_path / "long_vane.toml"
    bad.write_text(text.replace("length = 0.012", "length = 0.03", 1), encoding="utf-8")
    assert load_config(bad).values["vane.length"] == 0.03
    for check in (checked_config, pumpsim.load_config):
        with pytest.raises(ConfigError, match="vane.length .* too long"):
            check(bad)


# -- size and privacy rules: on once every part of the redesign is merged --------------------------

def _private_imports() -> list:
    """(module, name) for every `from X import _name` where X is another module of the tree."""
    mods = source_modules()
    out = []
    for module, path in mods.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and _targets(module, path, node, mods):
                out += [(module, a.name) for a in node.names
                        if a.name.startswith("_") and not a.name.startswith("__")]
    return sorted(out)


def test_no_module_over_600_lines():
    big = sorted((n, m) for m, p in source_modules().items()
                 if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES)
    assert big == []


def test_no_function_over_60_lines():
    long = []
    for module, path in source_modules().items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long.append((n, f"{module}.{node.name}"))
    assert sorted(long) == []


def test_no_private_name_imported_across_modules():
    assert _private_imports() == []


TOP = ("pumpsim.api", "pumpsim.cli", "pumpsim.report", "pumpsim.__main__")
# the one call from below into the top layer: SimulationResult.plot(), a convenience that hands the
# result to its figure module when called (as pandas' DataFrame.plot does); nothing else may
UPWARD_ALLOWED = {("pumpsim.result", "pumpsim.report.simulation")}


def _in(module: str, packages) -> bool:
    return any(module == p or module.startswith(p + ".") for p in packages)


def test_nothing_below_the_top_layer_imports_the_api_the_cli_or_the_reports():
    """Rendering, the API and the command line sit on top: no algorithm, kernel or data module
    reaches up into them (the package's own lazy __init__ names its public functions only)."""
    graph = import_graph()
    upward = sorted((m, t) for m, ts in graph.items() for t in ts
                    if not _in(m, TOP) and m != "pumpsim" and _in(t, TOP) and (m, t) not in UPWARD_ALLOWED)
    assert upward == []


def test_the_reports_import_no_algorithm_package():
    """A page draws a result object: the report package imports no fitting, diagnosis, study or
    integration module (it may import the bottom layer: statistics, formatting, files)."""
    algorithms = ("pumpsim.identification", "pumpsim.diagnosis", "pumpsim.design.execute",
                  "pumpsim.design.optimiser", "pumpsim.design.indices", "pumpsim.pneumatics.run",
                  "pumpsim.simulate", "pumpsim.constrained", "pumpsim.contact")
    graph = import_graph()
    reaching = sorted((m, t) for m, ts in graph.items() if _in(m, ("pumpsim.report",)) for t in ts
                      if _in(t, algorithms))
    assert reaching == []


def test_no_two_test_files_share_a_name():
    """pytest imports a test module by its basename (rootdir-relative, no packages): two test
    files of one name in different folders stop the whole run at collection."""
    seen = defaultdict(list)
    for p in (ROOT / "tests").rglob("test_*.py"):
        seen[p.name].append(str(p.relative_to(ROOT)))
    assert not {n: ps for n, ps in seen.items() if len(ps) > 1}
