"""The notify task (`workers.tasks.run_notify`) run eagerly in this process: which failures Celery retries,
how often and after how long, and what finishes the node."""

from typing import Any

import celery.app.autoretry
import pytest
import requests
from django.conf import settings

from workers import tasks

URL = "http://notify.invalid/done"


@pytest.fixture
def finished(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """What the task finished the node with; the node is running, its notify goes to URL."""
    calls: list[dict[str, Any]] = []
    params = {"url": URL, "json_data": {"n": 1}, "timeout": 5}
    monkeypatch.setattr(tasks.mission_selectors, "notify_params", lambda **_: params)
    monkeypatch.setattr(tasks, "mission_notify_finished", lambda **kwargs: calls.append(kwargs))
    return calls


@pytest.fixture
def countdowns(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """The seconds Celery waited before each retry."""
    seen: list[float] = []
    backoff = celery.app.autoretry.get_exponential_backoff_interval

    def recorded(**kwargs: Any) -> float:
        seen.append(backoff(**kwargs))
        return seen[-1]

    monkeypatch.setattr(celery.app.autoretry, "get_exponential_backoff_interval", recorded)
    return seen


def _answers(monkeypatch: pytest.MonkeyPatch, *outcomes: int | Exception) -> list[str]:
    """requests.post answers each call with the next status (or raises the next exception)."""
    posted: list[str] = []
    left = list(outcomes)

    def post(url: str, **_: Any) -> requests.Response:
        posted.append(url)
        outcome = left.pop(0)
        if isinstance(outcome, Exception):
            raise outcome
        response = requests.Response()
        response.status_code = outcome
        return response

    monkeypatch.setattr(tasks.requests, "post", post)
    return posted


def test_retryable_failures_are_retried_with_doubling_backoff_until_the_call_succeeds(
    monkeypatch: pytest.MonkeyPatch, finished: list[dict[str, Any]], countdowns: list[float]
) -> None:
    posted = _answers(monkeypatch, 503, requests.ConnectionError("refused"), 200)

    tasks.run_notify.apply(("m", "tell"))

    assert len(posted) == 3
    assert countdowns == [settings.NOTIFY_BACKOFF_SECONDS, 2 * settings.NOTIFY_BACKOFF_SECONDS]
    assert finished == [{"mission": "m", "node": "tell", "success": True, "error_msg": None}]


def test_a_call_still_failing_after_its_retries_fails_the_node(
    monkeypatch: pytest.MonkeyPatch, finished: list[dict[str, Any]], countdowns: list[float]
) -> None:
    posted = _answers(monkeypatch, *[500] * (settings.NOTIFY_RETRIES + 1))

    tasks.run_notify.apply(("m", "tell"))

    assert len(posted) == settings.NOTIFY_RETRIES + 1
    assert countdowns == [settings.NOTIFY_BACKOFF_SECONDS * 2**n for n in range(settings.NOTIFY_RETRIES)]
    assert finished == [
        {"mission": "m", "node": "tell", "success": False, "error_msg": f"Notify got HTTP 500 from {URL}"}
    ]


@pytest.mark.parametrize("status", [400, 404, 201])
def test_a_status_the_reference_does_not_retry_fails_the_node_at_once(
    monkeypatch: pytest.MonkeyPatch, finished: list[dict[str, Any]], countdowns: list[float], status: int
) -> None:
    posted = _answers(monkeypatch, status)

    tasks.run_notify.apply(("m", "tell"))

    assert len(posted) == 1 and countdowns == []
    assert finished == [
        {
            "mission": "m",
            "node": "tell",
            "success": False,
            "error_msg": f"Notify got HTTP {status} from {URL}",
        }
    ]
