"""Robots whose factsheet was stored before robots 0012 get its supported zone types (`supported_zones` is
written when a factsheet arrives; one that arrived before would leave a 3.0 robot without zone sets until it
sent another)."""

from typing import Any

from django.db import migrations

from vda5050.zones import supported_zones


def backfill(apps: Any, schema_editor: Any) -> None:
    Robot = apps.get_model("robots", "Robot")
    for robot in Robot.objects.filter(factsheet__isnull=False, supported_zones=[]).only("name", "factsheet"):
        zones = supported_zones(robot.factsheet)
        if zones:
            Robot.objects.filter(name=robot.name).update(supported_zones=zones)


class Migration(migrations.Migration):
    dependencies = [
        ("robots", "0013_responses_header_id_on_the_robot"),
    ]

    operations = [migrations.RunPython(backfill, migrations.RunPython.noop)]
