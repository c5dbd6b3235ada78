"""The README's curl commands work with authentication on: each sends the development token."""

import re
from pathlib import Path

from tests.access.endpoints import PUBLIC_PATHS

README = (Path(__file__).resolve().parents[2] / "README.md").read_text()
CURL = re.compile(r"curl (?P<options>[^`\n]*?)'?localhost:5000(?P<path>/[^\s'`?]*)")


def test_every_curl_of_a_protected_endpoint_sends_the_token():
    commands = list(CURL.finditer(README))

    assert len(commands) >= 10
    for command in commands:
        if command["path"] not in PUBLIC_PATHS:
            assert '-H "Authorization: Bearer $TOKEN"' in command["options"], command[0]


def test_the_token_comes_from_where_make_run_keeps_it():
    assert "export TOKEN=$(cat .fleet/dev-token)" in README
