"""REST requests on the API process (fleet.asgi.RestHandler: the request, the view and the response's close
in one call on a lent thread) through a real granian server and the test database: writes, errors, a
streamed static file, and the threads keeping their database connections."""

from pathlib import Path

import requests

from tests.changes.conftest import API_THREADS, server_connections

ROOT = Path(__file__).resolve().parents[2]


def test_rest_requests_write_read_and_refuse_through_the_real_server(stream_server):
    url, auth = stream_server.url, stream_server.auth
    created = requests.post(f"{url}/robot", json={"name": "rp-1"}, headers=auth, timeout=10)
    assert created.status_code == 200, created.text
    assert requests.get(f"{url}/robot/rp-1", headers=auth, timeout=10).json()["name"] == "rp-1"
    refused = requests.post(f"{url}/robot", json={"name": 5}, headers=auth, timeout=10)
    assert refused.status_code == 400
    assert refused.json()["detail"]
    assert requests.get(f"{url}/robot/rp-1", timeout=10).status_code == 401


def test_a_static_file_is_streamed_whole(stream_server):
    """WhiteNoise answers with a streamed file response, which is closed only after it is sent."""
    path = "fleetpage/static/vendor/leaflet/leaflet.js"
    for _ in range(3):
        response = requests.get(f"{stream_server.url}/static/vendor/leaflet/leaflet.js", timeout=10)
        assert response.status_code == 200
        assert response.content == (ROOT / path).read_bytes()


def test_the_request_threads_keep_their_connections(stream_server):
    """request_finished runs on the request's thread: with persistent connections it keeps them, so 40
    requests use at most FLEET_API_THREADS connections."""
    for _ in range(40):
        assert requests.get(f"{stream_server.url}/robot", headers=stream_server.auth, timeout=10).ok
    assert 1 <= server_connections() <= API_THREADS
