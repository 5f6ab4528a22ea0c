"""The dependency direction of DESIGN.md, as an allow-list import-linter cannot express."""
import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
ALLOWED = {
    # net_kernel needs only numpy and numba (and the standard library).
    "net_kernel": {"numpy", "numba", "net_kernel"},
    # engine: no sockets, processes or zmq; net_kernel below it is fine.
    "engine": {"numpy", "numba", "engine", "net_kernel"},
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
