"""bench.house: its circles and floors on small import graphs, and its report on this repository."""

import subprocess
import sys

import grimp

from bench import house
from tests.deploy.layout import ROOT


def graph(*imports: tuple[str, str]) -> grimp.ImportGraph:
    built = grimp.ImportGraph()
    for importer, imported in imports:
        built.add_module(importer)
        built.add_module(imported)
        built.add_import(importer=importer, imported=imported)
    return built


def test_a_circle_is_found_once_with_every_module_in_it() -> None:
    found = house.circles(graph(("a.x", "b.y"), ("b.y", "c.z"), ("c.z", "a.x"), ("c.z", "d")))
    assert found == [["a.x", "b.y", "c.z"]]


def test_a_graph_without_circles_has_none() -> None:
    assert house.circles(graph(("a.x", "b.y"), ("a.x", "c.z"), ("b.y", "c.z"))) == []


def test_a_module_is_on_its_top_level_packages_floor() -> None:
    floors = [{"fleet"}, {"workers", "agents"}, {"kit"}]
    assert [house.floor_of(m, floors) for m in ("fleet.urls", "agents.tools", "kit.db", "simulator")] == [
        0,
        1,
        2,
        None,
    ]


def test_the_report_reads_the_layers_contract_and_measures_this_repository() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "bench.house"], cwd=ROOT, capture_output=True, text=True, check=True
    )
    lines = done.stdout.splitlines()
    assert lines[0].endswith(f"on {len(house.layers())} floors")
    assert "import circles: 0" in lines
    assert any(line.startswith("imports that run back up a floor: ") for line in lines)
