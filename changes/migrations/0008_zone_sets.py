"""Zone sets join the feed (change kind `zone_set`): their table gets 0003's triggers, its image leaving out
only `updated_at`, as stations' does (0005)."""

import importlib

from django.db import migrations, models

# 0003's function and the triggers it makes, which this gives the zone sets table too.
images = importlib.import_module("changes.migrations.0003_images_of_what_the_api_shows")

TABLE = "zones_zoneset"
UNSHOWN = {TABLE: ("zone_set", ("updated_at",))}


def _make_triggers(apps, schema_editor) -> None:
    connection = schema_editor.connection
    kind, unshown = UNSHOWN[TABLE]
    with connection.cursor() as cursor:
        columns = [c.name for c in connection.introspection.get_table_description(cursor, TABLE)]
        cursor.execute(images.triggers_sql(TABLE, kind, unshown, columns))


def _drop_triggers(apps, schema_editor) -> None:
    with schema_editor.connection.cursor() as cursor:
        cursor.execute(images.initial._drop_triggers(TABLE))


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0007_robot_state_since_operating_mode_shown"),
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
        migrations.RunPython(_make_triggers, _drop_triggers),
    ]
