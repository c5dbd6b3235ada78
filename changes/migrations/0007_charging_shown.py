"""A mission's purpose (missions 0009) and a robot's charge request and charging waiting reason (robots 0008)
are shown: the missions' and robots' triggers are made again so that the update triggers compare them (see
0003)."""

import importlib

from django.db import migrations

# 0003's function and the columns it leaves out (0004's, for missions), over the tables' columns now.
images = importlib.import_module("changes.migrations.0003_images_of_what_the_api_shows")
missions = importlib.import_module("changes.migrations.0004_mission_progress_unshown")

ROBOTS = "robots_robot"
ROBOT_KIND, ROBOT_UNSHOWN = missions.UNSHOWN[ROBOTS]
NEW_ROBOT_SHOWN = ("charge_requested", "charging_waiting_reason")
NEW_MISSION_SHOWN = ("purpose",)


def _make_robot_triggers(leave_out: tuple[str, ...]):
    """Make the robot table's triggers again, comparing its columns but `leave_out` (those about to go,
    going back)."""

    def make(apps, schema_editor) -> None:
        connection = schema_editor.connection
        with connection.cursor() as cursor:
            columns = [c.name for c in connection.introspection.get_table_description(cursor, ROBOTS)]
            cursor.execute(images.initial._drop_triggers(ROBOTS))
            shown = [column for column in columns if column not in leave_out]
            cursor.execute(images.triggers_sql(ROBOTS, ROBOT_KIND, ROBOT_UNSHOWN, shown))

    return make


class Migration(migrations.Migration):
    dependencies = [
        ("changes", "0006_mission_assignment_shown"),
        ("missions", "0009_mission_purpose"),
        ("robots", "0008_robot_charging"),
    ]

    operations = [
        migrations.RunPython(
            missions._make_triggers(missions.UNSHOWN[missions.TABLE][1], ()),
            missions._make_triggers(missions.UNSHOWN[missions.TABLE][1], NEW_MISSION_SHOWN),
        ),
        migrations.RunPython(_make_robot_triggers(()), _make_robot_triggers(NEW_ROBOT_SHOWN)),
    ]
