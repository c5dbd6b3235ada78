"""The feed records what the API shows: a row's image leaves out the columns only the dispatch core reads,
and an UPDATE that changed nothing else records nothing.

Before, every step that sent a robot a message recorded the robot (its outbox and headerIds changed) and
every order a robot took recorded its mission (order_accepted): rows of a kilobyte or more each that no
watcher was ever sent, as the stream drops an object whose image shows nothing new. updated_at, which no
representation shows, written with them decides nothing.

Only an UPDATE that changed an unshown column pays for comparing the row's images before and after
(`changes_unshown_update`); the others, such as the bridge's status flush of every moving robot each
second, are recorded as before (`changes_update`).
"""

from django.db import migrations

TABLE = "changes_change"

# The columns of each table that no API representation, filter or page shows.
UNSHOWN = {
    "robots_robot": ("robot", ("outbox", "next_order_header_id", "next_instant_actions_header_id")),
    "missions_mission": ("mission", ("order", "attempts", "order_sent_at", "order_accepted")),
}

# TG_ARGV: the kind, the unshown columns (comma-separated), and "compare" where an unshown column changed.
RECORD_FUNCTION = f"""
CREATE OR REPLACE FUNCTION changes_record() RETURNS trigger LANGUAGE plpgsql AS $$
DECLARE
    unshown text[] := coalesce(string_to_array(TG_ARGV[1], ','), '{{}}');
    image jsonb;
BEGIN
    IF TG_OP = 'DELETE' THEN
        INSERT INTO {TABLE} (kind, name, image)
        VALUES (TG_ARGV[0], OLD.name, jsonb_set(to_jsonb(OLD) - unshown, '{{lifecycle}}', '"DELETED"'));
        RETURN OLD;
    END IF;
    image := to_jsonb(NEW) - unshown;
    IF TG_ARGV[2] = 'compare' AND image - 'updated_at' = to_jsonb(OLD) - unshown - 'updated_at' THEN
        RETURN NEW;
    END IF;
    INSERT INTO {TABLE} (kind, name, image) VALUES (TG_ARGV[0], NEW.name, image);
    RETURN NEW;
END $$;
"""

# 0001's function, for going back.
WHOLE_ROW_FUNCTION = f"""
CREATE OR REPLACE FUNCTION changes_record() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    IF TG_OP = 'DELETE' THEN
        INSERT INTO {TABLE} (kind, name, image)
        VALUES (TG_ARGV[0], OLD.name, jsonb_set(to_jsonb(OLD), '{{lifecycle}}', '"DELETED"'));
        RETURN OLD;
    END IF;
    INSERT INTO {TABLE} (kind, name, image) VALUES (TG_ARGV[0], NEW.name, to_jsonb(NEW));
    RETURN NEW;
END $$;
"""


def _row(record: str, columns: tuple[str, ...]) -> str:
    return "ROW(" + ", ".join(f'{record}."{column}"' for column in columns) + ")"


def _triggers(table: str, kind: str, unshown: tuple[str, ...]) -> str:
    """0001's triggers (the WHEN skips a write of the same values cheaply), with the unshown columns left
    out of the images and, where one of them changed, the images compared."""
    arguments = f"'{kind}', '{','.join(unshown)}'"
    old, new = _row("OLD", unshown), _row("NEW", unshown)
    return f"""
    DROP TRIGGER {table}_changes ON {table};
    DROP TRIGGER {table}_changes_update ON {table};
    CREATE TRIGGER {table}_changes AFTER INSERT OR DELETE ON {table}
        FOR EACH ROW EXECUTE FUNCTION changes_record({arguments});
    CREATE TRIGGER {table}_changes_update AFTER UPDATE ON {table}
        FOR EACH ROW WHEN (OLD.* IS DISTINCT FROM NEW.* AND {old} IS NOT DISTINCT FROM {new})
        EXECUTE FUNCTION changes_record({arguments});
    CREATE TRIGGER {table}_changes_unshown_update AFTER UPDATE ON {table}
        FOR EACH ROW WHEN ({old} IS DISTINCT FROM {new})
        EXECUTE FUNCTION changes_record({arguments}, 'compare');
    """


def _whole_row_triggers(table: str, kind: str) -> str:
    """0001's triggers."""
    return f"""
    DROP TRIGGER {table}_changes ON {table};
    DROP TRIGGER {table}_changes_update ON {table};
    DROP TRIGGER {table}_changes_unshown_update ON {table};
    CREATE TRIGGER {table}_changes AFTER INSERT OR DELETE ON {table}
        FOR EACH ROW EXECUTE FUNCTION changes_record('{kind}');
    CREATE TRIGGER {table}_changes_update AFTER UPDATE ON {table}
        FOR EACH ROW WHEN (OLD.* IS DISTINCT FROM NEW.*) EXECUTE FUNCTION changes_record('{kind}');
    """


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0002_trim_mark"),
        ("robots", "0007_robot_map_action"),
    ]

    operations = [
        migrations.RunSQL(RECORD_FUNCTION, WHOLE_ROW_FUNCTION),
        *(
            migrations.RunSQL(_triggers(table, kind, unshown), _whole_row_triggers(table, kind))
            for table, (kind, unshown) in UNSHOWN.items()
        ),
    ]
