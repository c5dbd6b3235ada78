"""The MQTT bridge: robots' messages in, live state to Redis, coalesced status to PostgreSQL, steps queued.

Per state message it costs one parse and one pipelined Redis script call; the database sees one batched
UPDATE per flush period for the robots whose status changed, and a step runs only when something the
engine cares about changed (`dispatch.held.state_digest`). A robot that only took the order its last
step sent needs no step either (`dispatch.held.takes_order_only`): the flush marks the order accepted,
so that the sweep does not send it again. The bridge runs no step itself: it queues them for the Celery
step workers (`workers.step_requests.HeldSteps`), one request per batch of states, held while the workers
have a backlog until the requests fill a task. Several bridges may
run at once with an MQTT shared subscription (`FLEET_BRIDGE_SHARE_GROUP`): the Redis script orders each
robot's states by the robot's own timestamp and headerId, so it does not matter which bridge sees what.
A message it cannot take is dropped and counted by reason (`Drop`), one older than the robot's last on its
topic is ignored and counted (`Ignored`); either way the rest of the batch goes on (README, Metrics).

Its rooms:
- `loop`: the batch loop (`Bridge`): MQTT in, a batch at a time through one Redis pipeline, steps queued.
- `gate`: the message gate: parsing, ordering and validation of a message (`read`), drop accounting
  (`Drop`, `Ignored`, `DropLog`).
- `directory`: the robot directory (`RobotDirectory`): which robot a topic belongs to, and its version.
- `status_writer`: the robots' reported columns (`RobotStatus`) and the thread that writes them, coalesced
  (`StatusWriter`, one `Flush` per period).
"""
