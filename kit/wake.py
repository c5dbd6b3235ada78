"""The one port through which domain services ask the dispatch engine to step robots.

Services record a change and say which robots it concerns; how their steps get queued (Celery, in
`workers.steps`) is installed here by the workers app, so the services never import the workers.
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
    """Queue a step for each robot; a requester that cannot queue them now does so once it can."""
    if _requester is None:
        raise RuntimeError("no step requester installed: is the workers app in INSTALLED_APPS?")
    _requester(list(names))


def wake_robot(name: str) -> None:
    """Step robot `name` once the current transaction commits (so the step sees the change); the change
    is committed whether or not the step can be queued at once."""
    transaction.on_commit(lambda: request_steps([name]))
