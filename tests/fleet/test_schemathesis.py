"""Schemathesis against our own /openapi.json, served by a real server (granian) on the test database.

Every phase (the schema's examples, coverage of its edge values, fuzzing, stateful sequences that create,
read, change and delete robots and missions) with a fixed example budget, deterministic, so a run is
reproducible and a failure replays. The checks: no 5xx; every status code, content type, header and body
documented; every request that violates the schema refused; unsupported methods and missing required
headers answered as documented; every operation that declares credentials refuses requests without them
(ignored_auth). README.md ("Limits") tells how to run a bigger budget by hand.
"""

import os
import subprocess
import sys

import pytest

# Test cases per API operation and phase: about 1,500 requests, under two minutes on a slow machine.
EXAMPLES = int(os.environ.get("FLEET_TEST_SCHEMATHESIS_EXAMPLES", "30"))
CHECKS = (
    "not_a_server_error",
    "status_code_conformance",
    "content_type_conformance",
    "response_headers_conformance",
    "response_schema_conformance",
    "negative_data_rejection",
    "unsupported_method",
    "missing_required_header",
    "ignored_auth",
)
RUN_SECONDS = 600


@pytest.mark.timeout(RUN_SECONDS + 60)
def test_the_api_answers_every_generated_request_as_its_schema_says(api_server, tmp_path):
    headers = [option for name, value in api_server.auth.items() for option in ("-H", f"{name}: {value}")]

    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "schemathesis.cli",
            "run",
            f"{api_server.url}/openapi.json",
            "--checks",
            ",".join(CHECKS),
            "--max-examples",
            str(EXAMPLES),
            "--generation-deterministic",
            "--workers",
            "1",
            "--no-color",
            *headers,
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=RUN_SECONDS,
    )

    assert run.returncode == 0, run.stdout[-20_000:] + run.stderr[-5_000:] + api_server.output()[-5_000:]
    assert " passed" in run.stdout and "generated" in run.stdout, run.stdout
