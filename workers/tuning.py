"""The workers' timing and size constants, each with why it has its value.

Measured choices, not operators' settings (those are `FLEET_` settings in `fleet/settings.py`). Read them
as `tuning.NAME` where they are used, so that a test that patches one here changes what the code reads.
"""

# --- the bridge (`workers.bridge`) -------------------------------------------------------------------------

# Messages handled per pipeline round trip. A batch's steps are requested once all of it is handled, so a
# backlog (the bridge starved of CPU for a moment) is worked off in small batches: with 2,000, a state
# that needs a step waited behind hundreds of periodic ones (bench/HISTORY.md, "What changed": N=2000).
BATCH_LIMIT = 100
# A batch also takes what arrives this long after its first message. A batch's Redis round trip costs the
# processing thread several times a state's own work, and without the window a busy fleet's batches held
# only a few states: a state now waits up to the window more, and the machine has that CPU for the steps
# (bench/HISTORY.md, "What changed").
BATCH_WINDOW_SECONDS = 0.002
DIRECTORY_REFRESH_SECONDS = 2.0  # an unknown robot triggers at most one directory reload this often
LAST_STATE_AT_PERIOD = 10.0  # seconds between last_state_at writes of a robot whose status is unchanged
FORGET_STATUS_SECONDS = 60.0  # a robot silent this long is forgotten until it is heard again
FAILURE_PAUSE_SECONDS = 1.0  # after an iteration failed (database or Redis unreachable)
# A message timestamped further ahead of this host's clock is dropped: stored, it would make every message
# the robot sends until then look older, and be ignored (a robot whose clock is this far off needs fixing).
FUTURE_TOLERANCE_SECONDS = 300.0
DROP_LOG_SECONDS = 10.0  # one log line per topic and reason this often, however many messages are dropped

# --- step requests (`workers.step_requests`) -------------------------------------------------------------

# A queued-step marker expires on its own, so a step lost with a killed worker cannot block later ones.
STEP_MARKER_SECONDS = 10
# While step tasks wait in the broker, the bridge holds its step requests until they fill a task, at most
# this long (`step_requests.HeldSteps`): a robot's step waits this much more at worst, in a backlog it would
# wait behind anyway; the longer, the fuller a busy fleet's tasks (bench/HISTORY.md, "The Celery hop").
STEP_HOLD_SECONDS = 0.02
# How long a queued assignment run keeps others from being queued, at most (its marker's expiry): a run lost
# with a killed worker delays the next by no more than this.
ASSIGNMENT_MARKER_SECONDS = 10
# Assignment runs start at most this often: a run's fixed cost (a task, the free robots' read) paid per
# mission posted would be most of an order's (issue 41), and a mission waits at most this much longer.
ASSIGNMENT_RUN_INTERVAL_SECONDS = 0.1
# A run that left no free robot idle says so for this long (step_requests.ASSIGNMENT_FLEET_BUSY_KEY): in a
# busy fleet, new missions ask for about one run per this; a robot freed without asking for a run (its
# battery reported charged, ...) waits no longer for a new mission.
ASSIGNMENT_FLEET_BUSY_SECONDS = 1.0
# The zone plan's (`missions.zone_plan`) queued-run marker expires as the assignment's; its runs start at most
# this often: a fleet whose robots each report progress asks for a run per node reached, and a run reads them
# all.
ZONES_MARKER_SECONDS = 10
ZONES_RUN_INTERVAL_SECONDS = 0.1
# A step request that could not be queued (Redis or the broker away) is tried again this often.
UNQUEUED_RETRY_SECONDS = 1.0

# --- retries and long-lived processes (`workers.long_lived`) ---------------------------------------------

# A failed step (PostgreSQL or Redis away) is tried again after this long, doubling per failure in a row;
# so is what a process does once at its start (`keep_trying`).
RETRY_FIRST_SECONDS = 0.5
RETRY_MAX_SECONDS = 10.0
# A thread whose reply came in takes the interpreter lock back only when the thread holding it lets go:
# at Python's default 5 ms a reply waited up to that long behind one thread's Python code, after every
# round trip of a step (bench/HISTORY.md has what 0.5 ms did to step latency).
SWITCH_INTERVAL_SECONDS = 0.0005

# --- the MQTT clients (`workers.mqtt`) -------------------------------------------------------------------

# How long a process's first message waits for the publisher's connection (the broker may be down).
FIRST_CONNECT_SECONDS = 5.0
