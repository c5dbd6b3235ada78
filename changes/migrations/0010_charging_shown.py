"""A mission's purpose (missions 0010) and a robot's charge request and charging waiting reason (robots 0010)
are shown: the missions' and robots' triggers are made again so that the update triggers compare them (see
0003)."""

import importlib

from django.db import migrations

# 0004's way of making a table's triggers again, and the columns each table leaves out.
previous = importlib.import_module("changes.migrations.0004_mission_progress_unshown")

MISSIONS, ROBOTS = previous.TABLE, "robots_robot"
MISSION_UNSHOWN, ROBOT_UNSHOWN = previous.UNSHOWN[MISSIONS][1], previous.UNSHOWN[ROBOTS][1]
NEW_MISSION_SHOWN = ("purpose",)
NEW_ROBOT_SHOWN = ("charge_requested", "charging_waiting_reason")


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0009_robot_zone_sets_shown"),
        ("missions", "0010_mission_purpose"),
        ("robots", "0010_robot_charging"),
    ]

    operations = [
        migrations.RunPython(
            previous._make_triggers(MISSION_UNSHOWN, ()),
            previous._make_triggers(MISSION_UNSHOWN, NEW_MISSION_SHOWN),
        ),
        migrations.RunPython(
            previous._make_triggers(ROBOT_UNSHOWN, (), table=ROBOTS),
            previous._make_triggers(ROBOT_UNSHOWN, NEW_ROBOT_SHOWN, table=ROBOTS),
        ),
    ]
