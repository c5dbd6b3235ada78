"""The function a mission's creation calls in its INSERT statement (`missions.services.MISSION_INSERT_SQL`):
whether the new mission is queued behind others, read after taking the robot's queue lock shared.

A statement's own snapshot is taken before anything in it runs; a query in a volatile function takes a
new one when it runs, here after the lock. The lock's keys are `missions.rows.ROBOT_QUEUE_LOCK_SPACE`
and the robot's name hashed, as in `missions.rows.ROBOT_QUEUE_LOCK_SQL`.
"""

from django.db import migrations

CREATE = """
CREATE FUNCTION mission_queued_behind(new_robot varchar, new_position bigint) RETURNS boolean
LANGUAGE plpgsql VOLATILE AS $$
BEGIN
    PERFORM pg_advisory_xact_lock_shared(5050, hashtext(new_robot));
    RETURN EXISTS (
        SELECT 1 FROM missions_mission m
        WHERE m.robot = new_robot
          AND (m.state = 'RUNNING' OR m.state = 'PENDING' AND m.queue_position < new_position)
    );
END
$$
"""
DROP = "DROP FUNCTION mission_queued_behind(varchar, bigint)"


class Migration(migrations.Migration):
    dependencies = [("missions", "0004_autovacuum")]

    operations = [migrations.RunSQL(CREATE, DROP)]
