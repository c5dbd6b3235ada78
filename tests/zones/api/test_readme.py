"""The README's zone set commands ("Zone sets"), copied from it as they stand: the API takes the set, enables
it, and takes the 3.0 robot that then gets it."""

import re
from pathlib import Path

import orjson
import pytest

pytestmark = pytest.mark.django_db

SECTION = (Path(__file__).resolve().parents[3] / "README.md").read_text().split("### Zone sets", 1)[1]
SECTION = SECTION.split("\n### ", 1)[0]
PATH = re.compile(r"localhost:5000(/[^\s']*)")
BODY = re.compile(r"-d '([^']*)'")


def commands() -> list[tuple[str, str, dict | None]]:
    """(method, path, body) of each curl in the section, in order (a command may go on over lines ending in
    a backslash, its body over lines of its own)."""
    found = []
    for command in re.split(r"\ncurl ", SECTION.replace("\\\n", ""))[1:]:
        body = BODY.search(command)
        method = "POST" if body or command.startswith("-X POST") else "GET"
        found.append((method, PATH.search(command)[1], orjson.loads(body[1]) if body else None))
    return found


def test_the_readme_creates_and_enables_a_zone_set_and_the_robot_it_reaches(api) -> None:
    ran = []
    for method, path, body in commands():
        response = api.post(path, body or {}, format="json") if method == "POST" else api.get(path)
        assert response.status_code == 200, (path, response.content)
        ran.append((method, path))

    assert ran == [
        ("POST", "/zone_set"),
        ("POST", "/zone_set/floor1-v1/enable"),
        ("POST", "/robot"),
        ("GET", "/robot/carter30"),
    ]
    assert api.get("/zone_set/floor1-v1").json()["status"] == {"enabled": True}
    assert api.get("/robot/carter30").json()["vda5050"]["version"] == "3.0.0"
