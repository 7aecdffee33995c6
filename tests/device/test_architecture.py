"""The shape of device/ (issue 11): no import cycles, small modules, one handler per catalog command."""

from __future__ import annotations

import ast
from pathlib import Path

from pywsg.device.handlers import HANDLERS
from pywsg.protocol import CATALOG

DEVICE = Path(__file__).resolve().parents[2] / "src" / "pywsg" / "device"


def _module(path: Path) -> str:
    parts = list(path.relative_to(DEVICE).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports() -> dict[str, set[str]]:
    """device-internal imports of every module (type-only imports included: a Protocol, not the facade)."""
    graph: dict[str, set[str]] = {}
    for path in DEVICE.rglob("*.py"):
        name = _module(path)
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        if path.name == "__init__.py" and name == "":
            package = []
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level > 0:
                up = node.level - 1
                if up > len(package):
                    continue
                base = package[: len(package) - up]
                target = ".".join([*base, node.module] if node.module else base)
                if node.level - 1 == len(package) and (node.module or "").startswith("protocol"):
                    continue  # ..protocol from device/: outside the package
                if target.split(".")[0] == "protocol":
                    continue
                deps.add(target)
        graph[name] = deps
    return graph


def test_no_import_cycles_inside_device() -> None:
    graph = _imports()
    known = set(graph)
    state: dict[str, int] = {}
    cycle: list[str] = []

    def visit(node: str, stack: list[str]) -> None:
        state[node] = 1
        for dep in graph.get(node, ()):
            if dep not in known:
                continue
            if state.get(dep) == 1:
                cycle.extend([*stack, node, dep])
            elif dep not in state:
                visit(dep, [*stack, node])
        state[node] = 2

    for name in sorted(graph):
        if name not in state:
            visit(name, [])
    assert not cycle, " -> ".join(cycle)
    # plugins and fault injection depend on an interface, not on the facade
    for name in ("faults", "plugins.base", "plugins.ros_measure", "plugins.umi_measure", "axis", "health",
                 "streams", "schedule"):
        assert not graph[name] & {"gripper", "core", "handlers"}, (name, graph[name])


def test_no_module_over_700_lines() -> None:
    sizes = {_module(p) or "__init__": len(p.read_text().splitlines()) for p in DEVICE.rglob("*.py")}
    assert max(sizes.values()) <= 700, sizes


def test_every_catalog_command_has_one_handler() -> None:
    assert set(HANDLERS) == set(CATALOG)
