"""Factories for robots, missions and stations, in the shapes the API and the dispatch engine store them."""

from typing import Any

import factory
from django.utils import timezone

from dispatch.engine import initial_node_status, parse_tree
from missions.choices import FailureCategory, MissionState
from missions.models import Mission
from robots.models import Robot
from stations.choices import StationKind
from stations.models import Station
from zones.models import ZoneSet

# Who the tests' direct service calls are recorded as (WriteRecord.actor).
TEST_ACTOR = "test"
# A factsheet that lists startCharging: a robot the station plan may send to charge (issue 44).
CAN_CHARGE = {"protocolFeatures": {"agvActions": [{"actionType": "startCharging"}]}}


class RobotFactory(factory.django.DjangoModelFactory):
    """A robot with the default spec; its VDA 5050 serial number is its name, as the API makes it."""

    class Meta:
        model = Robot

    name = factory.Sequence(lambda number: f"robot{number:03d}")
    serial_number = factory.SelfAttribute("name")


class StationFactory(factory.django.DjangoModelFactory):
    """A charger for any robot, at the origin of no map."""

    class Meta:
        model = Station

    name = factory.Sequence(lambda number: f"station{number:03d}")
    kind = StationKind.CHARGER


class ZoneSetFactory(factory.django.DjangoModelFactory):
    """A disabled zone set of map `map` with one RELEASE zone, a 2 m square at the origin."""

    class Meta:
        model = ZoneSet

    name = factory.Sequence(lambda number: f"zones{number:03d}")
    map_id = "map"
    zones = factory.LazyFunction(
        lambda: [
            {
                "zone_id": "square",
                "zone_type": "RELEASE",
                "description": "",
                "vertices": [
                    {"x": 0.0, "y": 0.0},
                    {"x": 2.0, "y": 0.0},
                    {"x": 2.0, "y": 2.0},
                    {"x": 0.0, "y": 2.0},
                ],
                "release_loss_behavior": "STOP",
                "capacity": 1,
            }
        ]
    )


def route_node(name: str, *waypoints: tuple[float, float], parent: str = "root") -> dict[str, Any]:
    """A route node as stored: named, with its parent, and Pose2D waypoints with every default filled."""
    return {
        "name": name,
        "parent": parent,
        "route": {
            "waypoints": [
                {
                    "x": x,
                    "y": y,
                    "theta": 0.0,
                    "map_id": "",
                    "allowedDeviationXY": 0.1,
                    "allowedDeviationTheta": 0.0,
                }
                for x, y in waypoints or [(1.0, 2.0)]
            ]
        },
    }


def _node_status(mission: Any) -> dict[str, dict[str, Any]]:
    return initial_node_status(parse_tree(mission.mission_tree))


def _with_root(state: MissionState) -> Any:
    """node_status of a mission in `state`: every node PENDING, root mirroring the mission."""
    return factory.LazyAttribute(
        lambda mission: {**_node_status(mission), "root": {"state": state, "error_msg": None}}
    )


class MissionFactory(factory.django.DjangoModelFactory):
    """A queued mission of one route node; traits give the other states (running, completed, failed,
    canceled) with the timestamps the engine would have written."""

    class Meta:
        model = Mission

    class Params:
        running = factory.Trait(
            state=MissionState.RUNNING,
            start_timestamp=factory.LazyFunction(timezone.now),
            node_status=_with_root(MissionState.RUNNING),
        )
        completed = factory.Trait(
            state=MissionState.COMPLETED,
            start_timestamp=factory.LazyFunction(timezone.now),
            end_timestamp=factory.LazyFunction(timezone.now),
            node_status=_with_root(MissionState.COMPLETED),
        )
        failed = factory.Trait(
            state=MissionState.FAILED,
            start_timestamp=factory.LazyFunction(timezone.now),
            end_timestamp=factory.LazyFunction(timezone.now),
            failure_reason="Mission timed out",
            failure_category=FailureCategory.TIMEOUT,
            node_status=_with_root(MissionState.FAILED),
        )
        canceled = factory.Trait(
            state=MissionState.CANCELED,
            needs_canceled=True,
            end_timestamp=factory.LazyFunction(timezone.now),
            failure_category=FailureCategory.CANCELED,
            node_status=_with_root(MissionState.CANCELED),
        )

    name = factory.Sequence(lambda number: f"mission{number:03d}")
    robot = "carter01"
    mission_tree = factory.LazyFunction(lambda: [route_node("goto")])
    node_status = factory.LazyAttribute(_node_status)
