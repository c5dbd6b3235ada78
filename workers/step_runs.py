"""What a step task does for each of its robots (`step_and_publish`): run the robot's step
(`missions.robot_step.robot_step`), publish what it decided, count it, and queue its notify calls.

A step takes the robot's row lock, so steps of one robot never interleave whichever worker runs them, and
it reads the robot's latest stored state, so a duplicate or late step finds nothing to do.
"""

import time

from celery import current_app as app  # the roof's (fleet.celery), loaded with the settings
from django.conf import settings

from missions.robot_step import robot_step
from robots import livestate
from workers import metrics
from workers.publish import publish

NOTIFY_TASK = "fleet.run_notify"  # workers.tasks.run_notify, sent by name: the tasks import this module


def step_and_publish(name: str, *, requested_at: float | None = None) -> None:
    """Step robot `name`, then send what the step decided and count what happened.

    `requested_at` (epoch s) is when the cause happened: the step latency metric counts from there."""
    outcome = robot_step(name=name)
    counters = livestate.client().pipeline(transaction=False)
    if requested_at is not None and outcome.messages:
        metrics.observe_step_latency(time.time() - requested_at, pipe=counters)
    metrics.count(metrics.ORDER_REJECTIONS, by=outcome.rejections, pipe=counters)
    for mission in outcome.finished:
        metrics.count(
            metrics.MISSIONS_FINISHED,
            pipe=counters,
            state=mission.state,
            failure_category=mission.failure_category or "",
        )
    if outcome.wire:
        assert outcome.address is not None  # a step sends messages only to a robot it found
        publish(name=name, address=outcome.address, messages=outcome.wire, counters=counters)
    livestate.execute(counters)  # after the messages are out: the step's metrics wait, its robot does not
    for mission, node in outcome.notifies:
        app.send_task(NOTIFY_TASK, (mission, node), queue=settings.NOTIFY_QUEUE)
