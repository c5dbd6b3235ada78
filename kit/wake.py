"""The one port through which domain services ask the dispatch engine to step robots or to assign
missions.

Services record a change and say which robots it concerns (`request_steps`), or that unbound missions may
now find a robot (`request_assignment`), or that zones' grants may change (`request_zones_plan`); how those
get queued (Celery, `workers.step_requests.queue_steps_soon`, `queue_assignment_soon` and
`queue_zones_plan_soon`) is installed here by the workers app, so the services never import the workers.
"""

from collections.abc import Callable, Iterable

from django.db import transaction

StepRequester = Callable[[list[str]], None]
AssignmentRequester = Callable[[bool], None]  # its argument: `defer_while_busy`
ZonesRequester = Callable[[], None]

_requester: StepRequester | None = None
_assignment_requester: AssignmentRequester | None = None
_zones_requester: ZonesRequester | None = None


def install(
    requester: StepRequester, assignment_requester: AssignmentRequester, zones_requester: ZonesRequester
) -> None:
    """Set how steps, assignment runs and zone plan runs are queued (`workers.apps.WorkersConfig.ready`)."""
    global _requester, _assignment_requester, _zones_requester
    _requester = requester
    _assignment_requester = assignment_requester
    _zones_requester = zones_requester


def request_steps(names: Iterable[str]) -> None:
    """Step each robot once the current transaction commits (so the step sees the change; at once outside
    a transaction). The change is committed whether or not the steps can be queued at once: a requester
    that cannot queue them now does so once it can."""
    requester = _requester
    if requester is None:
        raise RuntimeError("no step requester installed: is the workers app in INSTALLED_APPS?")
    names = list(names)
    transaction.on_commit(lambda: requester(names))


def request_assignment(*, defer_while_busy: bool = False) -> None:
    """Run assignment (bind unbound missions to free capable robots) once the current transaction commits;
    requests made while one is queued are one run. Beat's periodic check makes up for a request lost.

    `defer_while_busy`: while the last run left no free robot idle, not until that news is old (a new
    mission: in a busy fleet the robots falling free take it, each in its own step)."""
    requester = _assignment_requester
    if requester is None:
        raise RuntimeError("no assignment requester installed: is the workers app in INSTALLED_APPS?")
    transaction.on_commit(lambda: requester(defer_while_busy))


def request_zones_plan() -> None:
    """Run the zone plan (`missions.zone_plan.zones_plan_run`: who holds which zone, how far each order
    reaches) once the current transaction commits; requests made while one is queued are one run. Beat runs
    it too while a map has an enabled zone set."""
    requester = _zones_requester
    if requester is None:
        raise RuntimeError("no zones requester installed: is the workers app in INSTALLED_APPS?")
    transaction.on_commit(requester)
