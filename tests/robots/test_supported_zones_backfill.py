"""robots 0014: a factsheet stored before the `supported_zones` column gives the robot its zone types."""

import importlib

import pytest
from django.apps import apps

from robots.models import Robot
from tests.factories import RobotFactory

pytestmark = pytest.mark.django_db

MIGRATION = importlib.import_module("robots.migrations.0014_supported_zones_from_stored_factsheets")


def test_robots_with_a_stored_3_0_factsheet_get_its_supported_zones_the_others_keep_none() -> None:
    zoned = RobotFactory(factsheet={"typeSpecification": {"supportedZones": ["RELEASE", "BLOCKED"]}})
    plain = RobotFactory(factsheet={"typeSpecification": {}})
    none = RobotFactory(factsheet=None)
    Robot.objects.update(supported_zones=[])

    MIGRATION.backfill(apps, None)

    assert dict(Robot.objects.values_list("name", "supported_zones")) == {
        zoned.name: ["RELEASE", "BLOCKED"],
        plain.name: [],
        none.name: [],
    }
