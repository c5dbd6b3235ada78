"""A robot's state_since and operating_mode (robots 0008) are shown: the robot's triggers are made again so
that the update trigger compares them (see 0003)."""

import importlib

from django.db import migrations

# 0004's way of making a table's triggers again; the robot's unshown columns are 0003's, unchanged since.
previous = importlib.import_module("changes.migrations.0004_mission_progress_unshown")

TABLE = "robots_robot"
UNSHOWN = previous.previous.UNSHOWN[TABLE][1]
NEW_SHOWN = ("state_since", "operating_mode")


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0006_mission_assignment_shown"),
        ("robots", "0008_robot_state_since_operating_mode"),
    ]

    operations = [
        migrations.RunPython(
            previous._make_triggers(UNSHOWN, (), table=TABLE),
            previous._make_triggers(UNSHOWN, NEW_SHOWN, table=TABLE),
        )
    ]
