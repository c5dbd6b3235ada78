"""Fixtures for bridge and robot_step tests: robots with unique names whose Redis keys are dropped after the
test, and a bridge that is never connected to MQTT."""

import uuid
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from robots import livestate
from robots.models import InstantAction, Robot
from robots.services import robot_create
from tests.factories import TEST_ACTOR
from vda5050.models import ActionStatus
from workers.bridge.loop import Bridge


@pytest.fixture
def make_robot(db: None) -> Iterator[Callable[..., Robot]]:
    """Creates robots (through the service) named uniquely for this test; forgets their live state after."""
    names: list[str] = []

    def make(prefix: str = "bridge", **spec: Any) -> Robot:
        robot = robot_create(
            actor=TEST_ACTOR, name=f"{prefix}-{uuid.uuid4().hex[:10]}", prefix=None, spec=spec
        )
        names.append(robot.name)
        return robot

    yield make
    for name in names:
        livestate.forget(name)
        livestate.client().delete(livestate.step_marker_key(name))


@pytest.fixture
def bridge() -> Bridge:
    """A bridge that only ever handles what a test hands it: run_forever (and so MQTT) is never called."""
    return Bridge()


@pytest.fixture
def robot(make_robot: Callable[..., Robot], bridge: Bridge) -> Robot:
    """A robot the bridge knows, whose creation-time factsheet request has been answered."""
    created = make_robot()
    InstantAction.objects.filter(robot=created).update(status=ActionStatus.FINISHED.value)
    bridge.directory.reload()
    return created
