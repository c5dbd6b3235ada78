"""Vacuum the churning tables often: every mission is inserted and then updated two or more times, and each
update leaves a dead row and dead index entries behind. PostgreSQL's defaults (20 % of the table) let a
large table collect millions of them, which the step's and the sweep's index scans over RUNNING and
PENDING missions then wade through. (Storage parameters only; they take effect where autovacuum is on.)"""

from django.db import migrations

TABLES = ("missions_mission", "robots_robot", "robots_instantaction")
PARAMETERS = {
    "autovacuum_vacuum_scale_factor": "0.02",
    "autovacuum_vacuum_threshold": "1000",
    "autovacuum_analyze_scale_factor": "0.02",
}


def _set(table: str) -> str:
    assignments = ", ".join(f"{name} = {value}" for name, value in PARAMETERS.items())
    return f"ALTER TABLE {table} SET ({assignments})"


def _reset(table: str) -> str:
    return f"ALTER TABLE {table} RESET ({', '.join(PARAMETERS)})"


class Migration(migrations.Migration):
    dependencies = [
        ("missions", "0003_sweep_indexes"),
        ("robots", "0002_instant_action"),
    ]

    operations = [migrations.RunSQL(_set(table), _reset(table)) for table in TABLES]
