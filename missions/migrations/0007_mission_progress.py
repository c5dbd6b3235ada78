"""The robot's progress on its mission's order, as a step last saw it change, and when: the stall clock of
an order taken and not executed, and how far a route got when the robot lost its order (`dispatch.faults`)."""

from django.db import migrations, models


class Migration(migrations.Migration):
    dependencies = [("missions", "0006_mission_index_writes")]

    operations = [
        migrations.AddField(
            model_name="mission",
            name="progress",
            field=models.JSONField(
                blank=True,
                help_text="The robot's progress on the order, as a step last saw it change.",
                null=True,
            ),
        ),
        migrations.AddField(
            model_name="mission",
            name="progress_seen_at",
            field=models.DateTimeField(
                blank=True,
                help_text="When the robot last showed progress on the order (its stall clock).",
                null=True,
            ),
        ),
    ]
