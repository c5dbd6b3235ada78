"""The one port through which domain services ask the dispatch engine to step robots.

Services record a change and say which robots it concerns (`request_steps`); how their steps get queued
(Celery, `workers.step_requests.queue_steps_soon`) is installed here by the workers app, so the services
never import the workers.
"""

from collections.abc import Callable, Iterable

from django.db import transaction

StepRequester = Callable[[list[str]], None]

_requester: StepRequester | None = None


def install(requester: StepRequester) -> None:
    """Set how steps are queued (`workers.apps.WorkersConfig.ready`)."""
    global _requester
    _requester = requester


def request_steps(names: Iterable[str]) -> None:
    """Step each robot once the current transaction commits (so the step sees the change; at once outside
    a transaction). The change is committed whether or not the steps can be queued at once: a requester
    that cannot queue them now does so once it can."""
    requester = _requester
    if requester is None:
        raise RuntimeError("no step requester installed: is the workers app in INSTALLED_APPS?")
    names = list(names)
    transaction.on_commit(lambda: requester(names))
