"""A robot's reported zone sets (robots 0009) are shown: the robot's triggers are made again so that the
update trigger compares them (see 0003)."""

import importlib

from django.db import migrations

# 0004's way of making a table's triggers again; the robot's unshown columns are 0003's, unchanged since.
previous = importlib.import_module("changes.migrations.0004_mission_progress_unshown")

TABLE = "robots_robot"
UNSHOWN = previous.previous.UNSHOWN[TABLE][1]
NEW_SHOWN = ("zone_sets",)


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0008_zone_sets"),
        ("robots", "0009_robot_zone_sets"),
    ]

    operations = [
        migrations.RunPython(
            previous._make_triggers(UNSHOWN, (), table=TABLE),
            previous._make_triggers(UNSHOWN, NEW_SHOWN, table=TABLE),
        )
    ]
