"""The feed records what the API shows: a row's image leaves out the columns no representation shows, and an
UPDATE records a change only when a column it shows changed.

Before, every step that sent a robot a message recorded the robot (its outbox and headerIds changed), every
order a robot took recorded its mission (order_accepted), and every idle robot was recorded each time the
bridge wrote its last_state_at: rows of a kilobyte or more that no watcher was ever sent, as the stream
drops an object whose image shows nothing new.

The update trigger's WHEN compares the shown columns, listed when the migration runs: a migration that adds
a column to either table must make the triggers again (`triggers_sql`), else a change of that column alone
goes unrecorded (tests/changes/test_feed_images.py checks that every column is compared or unshown).
"""

import importlib

from django.db import migrations

# 0001's table, function and triggers, which this replaces (and brings back, going back).
initial = importlib.import_module("changes.migrations.0001_initial")

# The columns of each table that no API representation, filter or page shows.
UNSHOWN = {
    "robots_robot": (
        "robot",
        ("outbox", "next_order_header_id", "next_instant_actions_header_id", "last_state_at", "updated_at"),
    ),
    "missions_mission": ("mission", ("order", "attempts", "order_sent_at", "order_accepted", "updated_at")),
}

# TG_ARGV: the kind, and the unshown columns (comma-separated), left out of the image.
RECORD_FUNCTION = f"""
CREATE FUNCTION changes_record() RETURNS trigger LANGUAGE plpgsql AS $$
DECLARE
    unshown text[] := string_to_array(TG_ARGV[1], ',');
BEGIN
    IF TG_OP = 'DELETE' THEN
        INSERT INTO {initial.TABLE} (kind, name, image)
        VALUES (TG_ARGV[0], OLD.name, jsonb_set(to_jsonb(OLD) - unshown, '{{lifecycle}}', '"DELETED"'));
        RETURN OLD;
    END IF;
    INSERT INTO {initial.TABLE} (kind, name, image) VALUES (TG_ARGV[0], NEW.name, to_jsonb(NEW) - unshown);
    RETURN NEW;
END $$;
"""
DROP_FUNCTION = "DROP FUNCTION changes_record();"


def triggers_sql(table: str, kind: str, unshown: tuple[str, ...], columns: list[str]) -> str:
    """The table's feed triggers: every insert and delete, and each UPDATE that changed a shown column."""
    shown = [column for column in columns if column not in unshown]
    arguments = f"'{kind}', '{','.join(unshown)}'"
    old, new = (
        "ROW(" + ", ".join(f'{record}."{column}"' for column in shown) + ")" for record in ("OLD", "NEW")
    )
    return f"""
    CREATE TRIGGER {table}_changes AFTER INSERT OR DELETE ON {table}
        FOR EACH ROW EXECUTE FUNCTION changes_record({arguments});
    CREATE TRIGGER {table}_changes_update AFTER UPDATE ON {table}
        FOR EACH ROW WHEN ({old} IS DISTINCT FROM {new}) EXECUTE FUNCTION changes_record({arguments});
    """


def _record_shown(apps, schema_editor) -> None:
    connection = schema_editor.connection
    with connection.cursor() as cursor:
        cursor.execute("".join(initial._drop_triggers(table) for table in UNSHOWN) + DROP_FUNCTION)
        cursor.execute(RECORD_FUNCTION)
        for table, (kind, unshown) in UNSHOWN.items():
            columns = [c.name for c in connection.introspection.get_table_description(cursor, table)]
            cursor.execute(triggers_sql(table, kind, unshown, columns))


def _record_whole_rows(apps, schema_editor) -> None:
    with schema_editor.connection.cursor() as cursor:
        cursor.execute("".join(initial._drop_triggers(table) for table in UNSHOWN) + DROP_FUNCTION)
        cursor.execute(initial.RECORD_FUNCTION)
        cursor.execute("".join(initial._triggers(table, kind) for table, (kind, _) in UNSHOWN.items()))


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0002_trim_mark"),
        ("robots", "0007_robot_map_action"),
    ]

    operations = [migrations.RunPython(_record_shown, _record_whole_rows)]
