"""Zone sets join the feed (change kind `zone_set`): their table gets 0003's triggers, its image leaving out
only `updated_at`, as stations' does (0005)."""

import importlib
from collections.abc import Callable

from django.db import migrations, models

# 0003's function and the triggers it makes, which this gives the zone sets table too.
images = importlib.import_module("changes.migrations.0003_images_of_what_the_api_shows")

TABLE = "zones_zoneset"
UNSHOWN = {TABLE: ("zone_set", ("updated_at",))}


def make_triggers(
    table: str, kind: str, unshown: tuple[str, ...], leave_out: tuple[str, ...] = ()
) -> Callable:
    """A RunPython function that makes the table's feed triggers (again, if it has them), leaving `unshown`
    out of the image and comparing every column but `leave_out` (those about to go, going back)."""

    def make(apps, schema_editor) -> None:
        connection = schema_editor.connection
        with connection.cursor() as cursor:
            cursor.execute("SELECT 1 FROM pg_trigger WHERE tgname = %s", [f"{table}_changes"])
            if cursor.fetchone() is not None:
                cursor.execute(images.initial._drop_triggers(table))
            columns = [c.name for c in connection.introspection.get_table_description(cursor, table)]
            shown = [column for column in columns if column not in leave_out]
            cursor.execute(images.triggers_sql(table, kind, unshown, shown))

    return make


def _drop_triggers(apps, schema_editor) -> None:
    with schema_editor.connection.cursor() as cursor:
        cursor.execute(images.initial._drop_triggers(TABLE))


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0006_mission_assignment_shown"),
        ("zones", "0001_initial"),
    ]

    operations = [
        migrations.AlterField(
            model_name="change",
            name="kind",
            field=models.CharField(
                choices=[
                    ("robot", "Robot"),
                    ("mission", "Mission"),
                    ("station", "Station"),
                    ("zone_set", "Zone Set"),
                ],
                max_length=10,
            ),
        ),
        migrations.RunPython(make_triggers(TABLE, *UNSHOWN[TABLE]), _drop_triggers),
    ]
