from django.db import models

from missions.choices import FailureCategory, Lifecycle, MissionPurpose, MissionState

QUEUE_POSITION_SEQUENCE = "missions_mission_queue_position_seq"


class NextQueuePosition(models.Func):
    """`nextval()` of the queue sequence: a FIFO position no two missions share, even across processes."""

    function = "nextval"
    template = f"%(function)s('{QUEUE_POSITION_SEQUENCE}')"
    output_field = models.BigIntegerField()

    def __init__(self) -> None:
        super().__init__()


class Mission(models.Model):
    """A behaviour-tree mission for one robot (or none yet: unbound, until assignment binds it): its spec
    (from the API) and its status (from the engine)."""

    name = models.CharField(max_length=100, primary_key=True)
    lifecycle = models.CharField(max_length=20, choices=Lifecycle.choices, default=Lifecycle.ALIVE)

    # --- spec ---
    robot = models.CharField(
        max_length=100,
        null=True,
        blank=True,
        help_text="Name of the robot; it need not exist yet. Null: unbound, assignment picks a robot.",
    )
    priority = models.IntegerField(default=0, help_text="Higher first in a robot's queue.")
    robot_selector = models.JSONField(
        null=True, blank=True, help_text="Who can run an unbound mission: labels, robot_types, action_types."
    )
    mission_tree = models.JSONField(help_text="Nodes in the API's shape, each with its name and parent.")
    purpose = models.CharField(
        max_length=20,
        choices=MissionPurpose.choices,
        null=True,
        blank=True,
        editable=False,
        help_text='A trip the dispatch core made itself: CHARGE or PARK (README "Stations"); null for a '
        "client's mission.",
    )
    timeout = models.FloatField(default=300.0, help_text="Seconds from start before the mission fails.")
    deadline = models.DateTimeField(null=True, blank=True)
    needs_canceled = models.BooleanField(default=False)
    update_nodes = models.JSONField(null=True, blank=True)

    # --- status ---
    state = models.CharField(max_length=20, choices=MissionState.choices, default=MissionState.PENDING)
    current_node = models.IntegerField(default=0)
    node_status = models.JSONField(default=dict)
    task_status = models.JSONField(default=dict)
    start_timestamp = models.DateTimeField(null=True, blank=True)
    end_timestamp = models.DateTimeField(null=True, blank=True)
    failure_reason = models.TextField(null=True, blank=True)
    failure_category = models.CharField(max_length=20, choices=FailureCategory.choices, null=True, blank=True)

    waiting_reason = models.TextField(
        null=True, blank=True, help_text="Why a queued mission has not started yet (e.g. low battery)."
    )
    assignment = models.JSONField(
        default=list,
        blank=True,
        help_text="The bindings assignment made of the mission: robot, bound_at, released_at, reason.",
    )

    # --- dispatch engine's record of the current leaf's VDA 5050 order ---
    order = models.JSONField(null=True, blank=True, help_text="Wire content of the current leaf's order.")
    order_sent_at = models.DateTimeField(null=True, blank=True)
    order_accepted = models.BooleanField(default=False)
    attempts = models.JSONField(default=dict, blank=True, help_text="Orders sent so far, per node name.")
    progress = models.JSONField(
        null=True, blank=True, help_text="The robot's progress on the order, as a step last saw it change."
    )
    progress_seen_at = models.DateTimeField(
        null=True, blank=True, help_text="When the robot last showed progress on the order (its stall clock)."
    )

    # Position in the robot's FIFO queue: missions of one robot run in ascending order.
    queue_position = models.BigIntegerField(db_default=NextQueuePosition(), editable=False)
    created_at = models.DateTimeField(auto_now_add=True)
    updated_at = models.DateTimeField(auto_now=True)

    class Meta:
        ordering = ["queue_position"]
        indexes = [
            models.Index(fields=["robot", "state", "queue_position"], name="mission_queue_idx"),
            models.Index(fields=["state"], name="mission_state_idx"),
            models.Index(fields=["start_timestamp"], name="mission_start_idx"),
            # Only the admin filters by lifecycle, and only the rare deleting missions are worth an index:
            # a full one got an entry at every update that moved a mission's row.
            models.Index(
                fields=["lifecycle"], condition=~models.Q(lifecycle="ALIVE"), name="mission_lifecycle_idx"
            ),
            # Beat's sweep looks for queued missions past their deadline and queued missions no step has
            # seen; partial indexes keep that cheap however many finished missions the table holds.
            models.Index(
                fields=["deadline"], condition=models.Q(state="PENDING"), name="mission_pending_deadline_idx"
            ),
            models.Index(
                fields=["created_at"],
                condition=models.Q(state="PENDING", waiting_reason__isnull=True),
                name="mission_unnoticed_idx",
            ),
            models.Index(fields=["robot"], condition=models.Q(state="RUNNING"), name="mission_running_idx"),
            # Assignment reads the unbound queue in its order (highest priority, oldest first): a run all of
            # it, a robot fallen free its first few; few rows, however many missions there are.
            models.Index(
                fields=["-priority", "queue_position"],
                condition=models.Q(state="PENDING", robot__isnull=True),
                name="mission_unbound_idx",
            ),
        ]

    def __str__(self) -> str:
        return self.name
