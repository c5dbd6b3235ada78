"""A robot's reported zone sets (robots 0008) are shown: the robot's triggers are made again so that the
update trigger compares them (see 0003)."""

import importlib

from django.db import migrations

previous = importlib.import_module("changes.migrations.0003_images_of_what_the_api_shows")

TABLE = "robots_robot"
KIND, UNSHOWN = previous.UNSHOWN[TABLE]
NEW_SHOWN = ("zone_sets",)


def _make_triggers(leave_out: tuple[str, ...]):
    """Make the robot table's triggers again, comparing its columns but `leave_out` (those about to go,
    going back)."""

    def make(apps, schema_editor) -> None:
        connection = schema_editor.connection
        with connection.cursor() as cursor:
            columns = [c.name for c in connection.introspection.get_table_description(cursor, TABLE)]
            cursor.execute(previous.initial._drop_triggers(TABLE))
            shown = [column for column in columns if column not in leave_out]
            cursor.execute(previous.triggers_sql(TABLE, KIND, UNSHOWN, shown))

    return make


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0007_zone_sets"),
        ("robots", "0008_robot_zone_sets"),
    ]

    operations = [migrations.RunPython(_make_triggers(()), _make_triggers(NEW_SHOWN))]
