"""A robot's zone set distribution (robots 0012): the zoneSet headerId counter and the moves made are the
dispatch core's alone, unshown like the other topics' counters and the outbox (a write of them alone
records nothing); the zone types its factsheet lists are shown (GET /robot's status.factsheet). The robot's
triggers are made again (see 0003)."""

import importlib

from django.db import migrations

# 0004's way of making a table's triggers again; the robot's unshown columns are 0003's, unchanged since.
previous = importlib.import_module("changes.migrations.0004_mission_progress_unshown")

TABLE = "robots_robot"
KIND, PREVIOUS_UNSHOWN = previous.UNSHOWN[TABLE]
NEW_UNSHOWN = ("next_zone_set_header_id", "zone_set_moves", "zone_set_moved_at")
NEW_SHOWN = ("supported_zones",)
UNSHOWN = {**previous.UNSHOWN, TABLE: (KIND, (*PREVIOUS_UNSHOWN, *NEW_UNSHOWN))}


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0011_robot_zone_access_shown"),
        ("robots", "0012_robot_zone_set_distribution"),
    ]

    operations = [
        migrations.RunPython(
            previous._make_triggers(UNSHOWN[TABLE][1], (), table=TABLE),
            previous._make_triggers(PREVIOUS_UNSHOWN, (*NEW_UNSHOWN, *NEW_SHOWN), table=TABLE),
        )
    ]
