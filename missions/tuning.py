"""The missions app's fixed periods and sizes, each with why it is what it is (an operator's knob is a
FLEET_ setting in fleet/settings.py instead)."""

# A queued mission no step has seen for this long, on a robot that runs nothing, gets a step from the sweep:
# its creation's wake-up was lost (Redis away, or the API killed between its commit and the wake-up).
UNNOTICED_MISSION_SECONDS = 2

# A running mission untouched this long whose robot has finished the mission's order gets a step: the last
# line of defence when the step that state asked for was lost.
STALLED_MISSION_SECONDS = 5

# Messages kept in a robot's outbox at most: those of its last steps that may not have gone out.
OUTBOX_LIMIT = 16

# A notify call waits at most a day (seconds): longer is no notification.
MAX_NOTIFY_TIMEOUT = 86_400

# A robot that falls free chooses its next mission among this many unbound ones (highest priority, oldest
# first: `missions.services.mission_claim`); one that suits none of them waits for the assignment run.
CLAIM_PAGE = 16
# Reads of that page per claim: robots falling free together take the same page's missions one by one, and
# a claim whose choices all went to others (2-3 % of claims at N=1000, bench/HISTORY.md "Assignment") reads it
# again rather than leave its robot idle for an assignment run.
CLAIM_TRIES = 2

# A charging trip that failed is tried again after this long, doubling per failure since the robot last
# charged, up to the maximum: a robot that cannot reach its charger does not loop on it.
TRIP_RETRY_SECONDS = 10.0
TRIP_RETRY_MAX_SECONDS = 600.0
