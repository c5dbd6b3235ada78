"""The README's example missions and robot, copied verbatim: the API must accept them as they are."""

import json

SIMPLE_MISSION_EXAMPLE = json.loads(
    """
{
"robot": "carter01",
"mission_tree": [
{
"name": "goto_pickup",
"parent": "root",
"route": {
"waypoints": [
{
"x": 1.5,
"y": 1.5,
"theta": 0,
"map_id": "map"
},
{
"x": 3.3,
"y": 2.1,
"theta": 0,
"map_id": "map"
}
]
}
},
{
"name": "goto_dropoff",
"parent": "root",
"route": {
"waypoints": [
{
"x": 4.0,
"y": 3.2,
"theta": 0,
"map_id": "map"
},
{
"x": 5.0,
"y": 5.0,
"theta": 0,
"map_id": "map"
}
]
}
}
],
"timeout": 300,
"deadline": "2023-09-28T04:04:24.013Z",
"needs_canceled": false,
"name": "simple_mission_example"
}
"""
)

COMPLEX_MISSION_EXAMPLE = json.loads(
    """
{
"robot": "carter01",
"mission_tree": [
{
"name": "goto_pickup",
"parent": "root",
"route": {
"waypoints": [
{
"x": 1.5,
"y": 0.8,
"theta": 0,
"map_id": "map"
}
]
}
},
{
"name": "pickup_book",
"parent": "root",
"action": {
"action_type": "dummy_action",
"action_parameters": {
"should_fail": 0,
"time": 1
}
}
},
{
"name": "route_fallback",
"parent": "root",
"selector": {}
},
{
"name": "goto_dropoff",
"parent": "route_fallback",
"route": {
"waypoints": [
{
"x": 3,
"y": 2.2,
"theta": 0,
"map_id": "map"
},
{
"x": 0.8,
"y": 1.8,
"theta": 0,
"map_id": "map"
}
]
}
},
{
"name": "goto_dropoff_seq",
"parent": "route_fallback",
"sequence": {}
},
{
"name": "reset_pose",
"parent": "goto_dropoff_seq",
"route": {
"waypoints": [
{
"x": 1.5,
"y": 0.8,
"theta": 0,
"map_id": "map"
}
]
}
},
{
"name": "dropoff_book",
"parent": "goto_dropoff_seq",
"action": {
"action_type": "dummy_action",
"action_parameters": {
"should_fail": 1,
"time": 1
}
}
},
{
"name": "dropoff_book_at_goal",
"parent": "root",
"action": {
"action_type": "dummy_action",
"action_parameters": {
"should_fail": 1,
"time": 1
}
}
}
],
"timeout": 300,
"deadline": "2023-09-28T04:04:24.013Z",
"needs_canceled": false,
"name": "complex_mission_example"
}
"""
)

MISSION_WITH_TELEOP = json.loads(
    """
{
"robot": "carter01",
"mission_tree": [
{
"name": "goto_pickup",
"parent": "root",
"route": {
"waypoints": [
{
"x": 5,
"y": 0,
"theta": 0,
"map_id": "map"
}
]
}
},
{
"name": "forklift_teleop",
"parent": "root",
"action": {
"action_type": "pause_order",
"action_parameters": {}
}
},
{
"name": "goto_dropoff",
"parent": "root",
"route": {
"waypoints": [
{
"x": 0,
"y": 0,
"theta": 0,
"map_id": "map"
}
]
}
}
],
"timeout": 300,
"deadline": "2023-11-01T00:21:31.112Z",
"needs_canceled": false,
"name": "mission_with_teleop"
}
"""
)

# "Missions for any capable robot": a mission posted without a robot.
UNBOUND_MISSION_EXAMPLE = json.loads(
    """
{
"robot_selector": {"labels": ["forklift"], "robot_types": [], "action_types": ["dummy_action"]},
"priority": 10,
"mission_tree": [
{"name": "goto_pickup", "parent": "root",
 "route": {"waypoints": [{"x": 1.5, "y": 0.8, "theta": 0, "map_id": "map"}]}},
{"name": "pickup_pallet", "parent": "root",
 "action": {"action_type": "dummy_action", "action_parameters": {"should_fail": 0, "time": 1}}}
],
"name": "unbound_mission_example"
}
"""
)

README_ROBOT = {"labels": [], "battery": {"critical_level": 0.1}, "heartbeat_timeout": 30, "name": "carter01"}

README_MISSIONS = {
    mission["name"]: mission
    for mission in (SIMPLE_MISSION_EXAMPLE, COMPLEX_MISSION_EXAMPLE, MISSION_WITH_TELEOP)
}
