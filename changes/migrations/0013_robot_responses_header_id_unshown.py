"""The robot's responses headerId counter (robots 0013, moved from the zone reach) is the dispatch core's
alone, unshown like the other topics' counters (a write of it alone records nothing). The robot's triggers
are made again (see 0003)."""

import importlib

from django.db import migrations

# 0004's way of making a table's triggers again; the robot's unshown columns as 0012 left them.
remade = importlib.import_module("changes.migrations.0004_mission_progress_unshown")
previous = importlib.import_module("changes.migrations.0012_robot_zone_set_distribution")

TABLE = "robots_robot"
KIND, PREVIOUS_UNSHOWN = previous.UNSHOWN[TABLE]
NEW_UNSHOWN = ("next_responses_header_id",)
UNSHOWN = {**previous.UNSHOWN, TABLE: (KIND, (*PREVIOUS_UNSHOWN, *NEW_UNSHOWN))}


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0012_robot_zone_set_distribution"),
        ("robots", "0013_responses_header_id_on_the_robot"),
    ]

    operations = [
        migrations.RunPython(
            remade._make_triggers(UNSHOWN[TABLE][1], (), table=TABLE),
            remade._make_triggers(PREVIOUS_UNSHOWN, NEW_UNSHOWN, table=TABLE),
        )
    ]
