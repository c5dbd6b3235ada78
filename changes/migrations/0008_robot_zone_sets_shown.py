"""A robot's reported zone sets (robots 0008) are shown: the robot's triggers are made again so that the
update trigger compares them (see 0003)."""

import importlib

from django.db import migrations

images = importlib.import_module("changes.migrations.0003_images_of_what_the_api_shows")
zone_sets = importlib.import_module("changes.migrations.0007_zone_sets")

TABLE = "robots_robot"
KIND, UNSHOWN = images.UNSHOWN[TABLE]
NEW_SHOWN = ("zone_sets",)


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0007_zone_sets"),
        ("robots", "0008_robot_zone_sets"),
    ]

    operations = [
        migrations.RunPython(
            zone_sets.make_triggers(TABLE, KIND, UNSHOWN),
            zone_sets.make_triggers(TABLE, KIND, UNSHOWN, NEW_SHOWN),
        )
    ]
