"""Fewer index entries per mission update. Most updates of a mission move its row (they change its state,
which indexes hold), so each writes an entry into every index of the table: with nine, those entries were
most of the write-ahead log a mission costs (~46 records) and what every vacuum cleans out of each index.
Two served no query: the full index on lifecycle (only the admin filters by it; now partial, holding the
rare deleting missions) and the `varchar_pattern_ops` index Django adds beside a CharField primary key
for LIKE lookups, which nothing makes (the admin's search is case-insensitive, which it cannot serve)."""

from django.db import migrations, models

LIKE_INDEX = "missions_mission_name_0573abce_like"  # Django's name for it, a hash of table and column


class Migration(migrations.Migration):
    dependencies = [("missions", "0005_mission_queued_behind")]

    operations = [
        migrations.RemoveIndex(model_name="mission", name="mission_lifecycle_idx"),
        migrations.AddIndex(
            model_name="mission",
            index=models.Index(
                condition=~models.Q(lifecycle="ALIVE"), fields=["lifecycle"], name="mission_lifecycle_idx"
            ),
        ),
        migrations.RunSQL(
            f"DROP INDEX IF EXISTS {LIKE_INDEX}",
            f"CREATE INDEX {LIKE_INDEX} ON missions_mission (name varchar_pattern_ops)",
        ),
    ]
