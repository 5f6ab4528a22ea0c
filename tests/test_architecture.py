"""The house rules import-linter cannot express: what each package may import (an allow-list), no
import cycle, no module over 700 lines, processes/ in its layers, and tests that share code only
through fixtures and tests/helpers/."""
import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
ALLOWED = {
    # net_kernel needs only numpy and numba (and the standard library), and threadpoolctl to hold
    # the net's modes to one BLAS thread (net_kernel/modes.py: the same bits in every process).
    "net_kernel": {"numpy", "numba", "net_kernel", "threadpoolctl"},
    # engine: no sockets, processes or zmq; net_kernel below it is fine; matplotlib draws the
    # replay's picture (engine/tools/render.py), which the Gymnasium environment
    # (engine/learning/env.py) renders; pettingzoo is the two-bat environment's API
    # (engine/learning/parallel_env.py); tomli_w writes a scene out as TOML (engine/physics/scene.py
    # scene_toml).
    "engine": {"numpy", "numba", "engine", "net_kernel", "matplotlib", "gymnasium", "pettingzoo", "tomli_w"},
}


def imported_roots(path: Path) -> set[str]:
    roots = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            roots.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            roots.add(node.module.split(".")[0])
    return roots


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_package_imports_only_what_it_may(package):
    stdlib = set(sys.stdlib_module_names) - {"multiprocessing", "socket", "subprocess", "threading", "asyncio"}
    for path in sorted((ROOT / package).rglob("*.py")):
        extra = imported_roots(path) - ALLOWED[package] - stdlib
        assert not extra, f"{path.relative_to(ROOT)} imports {sorted(extra)}"


PACKAGES = ("engine", "net_kernel", "processes", "bench")
MAX_MODULE_LINES = 700
# processes/ holds its layers as subpackages; directly in it only the package, its entry point
# and the supervisor.
PROCESSES_TOP = {"__init__.py", "__main__.py", "supervisor.py"}
# engine/ holds its rooms as subpackages (physics, play, learning, tools); directly in it only the
# package.
ENGINE_TOP = {"__init__.py"}


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _import_graph() -> dict[str, set[str]]:
    """Every module of the three packages -> the project modules it imports, anywhere in its body
    (inside functions too), except the command line's lazy imports inside its command functions."""
    paths = {_module_name(p): p for package in PACKAGES for p in (ROOT / package).rglob("*.py")}
    graph = {}
    for name, path in paths.items():
        lazy_ok = name.startswith("processes.cli")
        edges = set()
        tree = ast.parse(path.read_text(), str(path))
        top_level = set(map(id, tree.body))
        for node in ast.walk(tree):
            if lazy_ok and id(node) not in top_level:
                continue
            targets = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                # `from package import submodule` imports the submodule; a name defined in the
                # package's __init__ makes the package itself the target
                targets = [f"{node.module}.{alias.name}" if f"{node.module}.{alias.name}" in paths else node.module
                           for alias in node.names]
            for target in targets:
                while target and target not in paths:
                    target = target.rpartition(".")[0]
                if target and target != name:
                    edges.add(target)
        graph[name] = edges
    return graph


def test_no_import_cycle_counting_imports_inside_functions():
    graph = _import_graph()
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
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
                cycles.append(sorted(component))

    sys.setrecursionlimit(10_000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert not cycles, f"import cycles: {cycles}"


def test_no_module_over_700_lines():
    long = {str(p.relative_to(ROOT)): n for package in PACKAGES for p in (ROOT / package).rglob("*.py")
            if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines (split them by concept): {long}"


def test_processes_keeps_its_layers_in_subpackages():
    top = {p.name for p in (ROOT / "processes").glob("*.py")}
    assert top <= PROCESSES_TOP, f"modules directly in processes/ (move them into a layer): {sorted(top - PROCESSES_TOP)}"


def test_engine_keeps_its_rooms_in_subpackages():
    top = {p.name for p in (ROOT / "engine").glob("*.py")}
    assert top <= ENGINE_TOP, f"modules directly in engine/ (move them into a room): {sorted(top - ENGINE_TOP)}"


MAX_FUNCTION_LINES = 120
# Numba kernels are exempt: a kernel is one compiled loop, and splitting it costs calls in the
# hot path (their decorators: njit, or numba.njit / numba.jit).
KERNEL_DECORATORS = {"njit", "jit"}


def _is_kernel(node: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    for decorator in node.decorator_list:
        target = decorator.func if isinstance(decorator, ast.Call) else decorator
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in KERNEL_DECORATORS:
            return True
    return False


def test_no_function_over_120_lines_outside_numba_kernels():
    long = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not _is_kernel(node):
                    lines = node.end_lineno - node.lineno + 1
                    if lines > MAX_FUNCTION_LINES:
                        long[f"{path.relative_to(ROOT)}:{node.lineno} {node.name}"] = lines
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines (split them by what they do): {long}"


def test_no_test_module_imports_another_test_module_or_a_conftest():
    """Shared test code lives in fixtures (conftest.py, found by pytest) or in tests/helpers/; a
    test module imported as a module runs its tests twice and ties two rooms' tests together."""
    def is_test_module(name: str) -> bool:
        last = name.rsplit(".", 1)[-1]
        return name.split(".")[0] == "tests" and (last.startswith("test_") or last == "conftest")

    found = []
    for path in sorted((ROOT / "tests").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
            elif isinstance(node, ast.ImportFrom):  # relative: the suite imports by full names only
                found.append(f"{path.relative_to(ROOT)}: a relative import")
                continue
            else:
                continue
            found += [f"{path.relative_to(ROOT)} imports {name}" for name in names if is_test_module(name)]
    assert not found, f"test modules importing test modules (move the helper to tests/helpers/ or a fixture): {found}"


def test_every_import_of_a_project_module_names_one_that_exists():
    """A module moved or renamed leaves no import of its old name behind (import-linter passes over
    an import it cannot resolve, and a lazy one fails only when it runs)."""
    paths = {_module_name(p) for package in PACKAGES + ("bench", "tests") for p in (ROOT / package).rglob("*.py")}
    paths |= {name.rsplit(".", k)[0] for name in paths for k in range(1, name.count(".") + 1)}  # namespace packages
    missing = []
    for package in PACKAGES + ("bench", "tests", "examples"):
        for path in sorted((ROOT / package).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.Import):
                    names = [alias.name for alias in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names = [node.module]
                else:
                    continue
                missing += [f"{path.relative_to(ROOT)}: {name}" for name in names
                            if name.split(".")[0] in PACKAGES + ("bench", "tests") and name not in paths]
    assert not missing, f"imports of modules that do not exist: {missing}"
