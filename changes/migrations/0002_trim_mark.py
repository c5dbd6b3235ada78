"""The trim's mark: how far the change feed has been trimmed, so a stream knows whether it can resume."""

from django.db import migrations, models

TABLE = "changes_trim_mark"


class Migration(migrations.Migration):
    dependencies = [("changes", "0001_initial")]

    operations = [
        migrations.SeparateDatabaseAndState(
            state_operations=[
                migrations.CreateModel(
                    name="TrimMark",
                    fields=[
                        ("id", models.SmallIntegerField(default=1, primary_key=True, serialize=False)),
                        (
                            "xid",
                            models.BigIntegerField(
                                help_text="The newest writing transaction (xid8) of a deleted change."
                            ),
                        ),
                        ("trimmed_at", models.DateTimeField()),
                    ],
                    options={"db_table": TABLE},
                ),
            ],
            # xid8, as changes_change.xid, so the two compare without a cast.
            database_operations=[
                migrations.RunSQL(
                    f"CREATE TABLE {TABLE} (id smallint PRIMARY KEY DEFAULT 1 CHECK (id = 1), "
                    "xid xid8 NOT NULL, trimmed_at timestamptz NOT NULL);",
                    f"DROP TABLE {TABLE};",
                ),
            ],
        ),
    ]
