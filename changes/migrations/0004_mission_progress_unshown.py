"""The mission's progress and its stall clock (missions 0007) are the dispatch core's alone: unshown, left out
of the mission's image, and a write of them alone records nothing (see 0003)."""

import importlib

from django.db import migrations

# 0003's triggers and the columns they leave out, which this extends (and brings back, going back).
previous = importlib.import_module("changes.migrations.0003_images_of_what_the_api_shows")

TABLE = "missions_mission"
KIND, PREVIOUS_UNSHOWN = previous.UNSHOWN[TABLE]
NEW_UNSHOWN = ("progress", "progress_seen_at")
UNSHOWN = {**previous.UNSHOWN, TABLE: (KIND, (*PREVIOUS_UNSHOWN, *NEW_UNSHOWN))}


def _make_triggers(unshown: tuple[str, ...], leave_out: tuple[str, ...], table: str = TABLE):
    """Make the table's triggers again (the mission's unless told), leaving out `unshown`, comparing its
    columns but `leave_out` (those about to go, going back)."""
    kind = previous.UNSHOWN[table][0]

    def make(apps, schema_editor) -> None:
        connection = schema_editor.connection
        with connection.cursor() as cursor:
            columns = [c.name for c in connection.introspection.get_table_description(cursor, table)]
            cursor.execute(previous.initial._drop_triggers(table))
            shown = [column for column in columns if column not in leave_out]
            cursor.execute(previous.triggers_sql(table, kind, unshown, shown))

    return make


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0003_images_of_what_the_api_shows"),
        ("missions", "0007_mission_progress"),
    ]

    operations = [
        migrations.RunPython(
            _make_triggers(UNSHOWN[TABLE][1], ()), _make_triggers(PREVIOUS_UNSHOWN, NEW_UNSHOWN)
        )
    ]
