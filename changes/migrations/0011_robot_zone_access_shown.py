"""The zones a robot holds and waits for (robots 0011) are shown: the robots' triggers are made again so that
the update trigger compares the new column (see 0003)."""

import importlib

from django.db import migrations

# 0004's way of making a table's triggers again; the robot's unshown columns are 0003's, unchanged since.
previous = importlib.import_module("changes.migrations.0004_mission_progress_unshown")

TABLE = "robots_robot"
UNSHOWN = previous.previous.UNSHOWN[TABLE][1]
NEW_SHOWN = ("zone_access",)


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0010_charging_shown"),
        ("robots", "0011_robot_zone_access"),
    ]

    operations = [
        migrations.RunPython(
            previous._make_triggers(UNSHOWN, (), table=TABLE),
            previous._make_triggers(UNSHOWN, NEW_SHOWN, table=TABLE),
        ),
    ]
