"""A mission's priority, robot selector and assignment record (missions 0008) are shown: the mission's
triggers are made again so that the update trigger compares them (see 0003)."""

import importlib

from django.db import migrations

# 0004's triggers, made again over the table's columns now.
previous = importlib.import_module("changes.migrations.0004_mission_progress_unshown")

UNSHOWN = previous.UNSHOWN
NEW_SHOWN = ("priority", "robot_selector", "assignment")


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0005_stations"),
        ("missions", "0008_mission_assignment"),
    ]

    operations = [
        migrations.RunPython(
            previous._make_triggers(UNSHOWN[previous.TABLE][1], ()),
            previous._make_triggers(UNSHOWN[previous.TABLE][1], NEW_SHOWN),
        )
    ]
