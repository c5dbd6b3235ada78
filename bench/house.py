"""The house's shape, measured: import circles, imports that run back up a floor, and the largest rooms.

    .venv/bin/python -m bench.house

The floors are the layers contract's in pyproject.toml (read from it); an import runs back up a floor when
its importer's layer lies below the imported module's. Circles are strongly connected groups of modules
in the import graph (grimp's, as import-linter builds it). Results: bench/HISTORY.md, "The re-floored house".
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

import grimp

ROOT = Path(__file__).resolve().parent.parent
LARGE_ROOM_LINES = 900


def importlinter() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]


def layers() -> list[set[str]]:
    config = importlinter()
    [contract] = [c for c in config["contracts"] if c["type"] == "layers"]
    return [{name.strip() for name in layer.split("|")} for layer in contract["layers"]]


def floor_of(module: str, floors: list[set[str]]) -> int | None:
    package = module.split(".")[0]
    return next((index for index, floor in enumerate(floors) if package in floor), None)


def circles(graph: grimp.ImportGraph) -> list[list[str]]:
    """Tarjan's strongly connected components of more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = [0]

    def visit(module: str) -> None:
        index[module] = low[module] = counter[0]
        counter[0] += 1
        stack.append(module)
        on_stack.add(module)
        for imported in graph.find_modules_directly_imported_by(module):
            if imported not in index:
                visit(imported)
                low[module] = min(low[module], low[imported])
            elif imported in on_stack:
                low[module] = min(low[module], index[imported])
        if low[module] == index[module]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == module:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for module in sorted(graph.modules):
        if module not in index:
            visit(module)
    return found


def main() -> None:
    floors = layers()
    packages = sorted({name for floor in floors for name in floor})
    graph = grimp.build_graph(*packages)
    up = sorted(
        (importer, imported)
        for importer in graph.modules
        for imported in graph.find_modules_directly_imported_by(importer)
        if (a := floor_of(importer, floors)) is not None
        and (b := floor_of(imported, floors)) is not None
        and a > b
    )
    rooms = sorted(
        (sum(1 for _ in path.open()), str(path.relative_to(ROOT)))
        for package in importlinter()["root_packages"]
        for path in (ROOT / package).rglob("*.py")
        if "migrations" not in path.parts
    )
    print(f"modules: {len(graph.modules)} in {len(packages)} packages on {len(floors)} floors")
    print(f"import circles: {len(circles(graph))}")
    for circle in circles(graph):
        print("  " + " <-> ".join(circle))
    print(f"imports that run back up a floor: {len(up)}")
    for importer, imported in up:
        print(f"  {importer} -> {imported}")
    large = [(lines, path) for lines, path in rooms if lines > LARGE_ROOM_LINES]
    print(f"rooms over {LARGE_ROOM_LINES} lines: {len(large)}; the largest:")
    for lines, path in rooms[-5:][::-1]:
        print(f"  {lines:5d} {path}")


if __name__ == "__main__":
    os.chdir(ROOT)
    main()
