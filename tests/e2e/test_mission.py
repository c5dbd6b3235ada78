"""Reference scenarios `mission.py` and `mission_tree.py`: missions run to the expected status sequences."""

import math

import pytest

from tests.e2e.helpers import (
    StatusRecorder,
    action,
    composite,
    create_robot,
    get,
    post_mission,
    route,
    wait_mission,
    wait_robot,
)
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


def test_three_waypoint_route_completes_with_robot_on_task_then_idle(api, unique, recorder, simulated_robot):
    robot = simulated_robot("carter")
    wait_robot(api, robot, online=True)
    recorder_ = StatusRecorder(api, unique("m"))
    name = recorder_.name
    post_mission(api, name, robot, [route("r0", (6, 0), (6, 6), (2, 1))])  # long enough to see ON_TASK
    wait_robot(api, robot, state="ON_TASK")
    mission = wait_mission(api, name)
    sequence = recorder_.stop()
    assert mission["status"]["state"] == "COMPLETED"
    assert mission["status"]["node_status"]["r0"]["state"] == "COMPLETED"
    assert mission["status"]["node_status"]["root"]["state"] == "COMPLETED"
    assert mission["status"]["failure_reason"] is None
    assert sequence[-1] == ("COMPLETED", 0)
    assert [state for state, _ in sequence if state != "PENDING"] in (["RUNNING", "COMPLETED"], ["COMPLETED"])
    assert mission["status"]["start_timestamp"] <= mission["status"]["end_timestamp"]
    wait_robot(api, robot, state="IDLE")

    def arrived() -> bool:  # the pose reaches the database with the bridge's next status write
        pose = get(api, "robot", robot)["status"]["pose"]
        return math.isclose(pose["x"], 2, abs_tol=0.2) and math.isclose(pose["y"], 1, abs_tol=0.2)

    wait_for(arrived, message="the robot's pose at the last waypoint")
    orders = recorder.for_robot(robot, "order")
    assert len({o["orderId"] for o in orders}) == 1
    assert [n["sequenceId"] for n in orders[0]["nodes"]] == [0, 2, 4, 6]


def test_routes_in_sequence_step_current_node(api, unique, simulated_robot):
    robot = simulated_robot("carter")
    name = unique("m")
    recorder_ = StatusRecorder(api, name)
    post_mission(api, name, robot, [route("a", (1, 0)), route("b", (1, 1)), route("c", (0, 1))])
    mission = wait_mission(api, name)
    sequence = recorder_.stop()
    assert mission["status"]["state"] == "COMPLETED"
    running_nodes = [node for state, node in sequence if state == "RUNNING"]
    assert running_nodes == sorted(running_nodes)
    assert sequence[-1] == ("COMPLETED", 2)


def test_mission_for_robot_created_later_runs_once_robot_exists(api, simulator, unique):
    robot = unique("late")
    name = unique("m")
    post_mission(api, name, robot, [route("r", (1, 1))])
    assert get(api, "mission", name)["status"]["state"] == "PENDING"
    simulator(f"{robot},0,0")
    create_robot(api, robot)
    assert wait_mission(api, name)["status"]["state"] == "COMPLETED"


def test_failure_period_fails_every_second_mission_fifo(api, simulator, unique):
    robot = unique("flaky")
    simulator(f"{robot},0,0,0,map,2")
    create_robot(api, robot)
    names = [unique(f"m{i}") for i in range(4)]
    for i, name in enumerate(names):
        post_mission(api, name, robot, [route("r", (i + 1, 0))])
    states = [wait_mission(api, name)["status"] for name in names]
    assert [s["state"] for s in states] == ["COMPLETED", "FAILED", "COMPLETED", "FAILED"]
    assert states[1]["failure_category"] == "ROBOT_APP"
    assert "Failure period reached" in states[1]["failure_reason"]
    assert states[1]["node_status"]["r"]["state"] == "FAILED"
    starts = [s["start_timestamp"] for s in states]
    assert starts == sorted(starts)


def test_timeout_fails_mission_and_sends_cancel_order(api, unique, recorder, simulated_robot):
    robot = simulated_robot("slow")
    name = unique("m")
    post_mission(api, name, robot, [route("far", (500, 0))], timeout=1)
    mission = wait_mission(api, name)
    assert mission["status"]["state"] == "FAILED"
    assert mission["status"]["failure_reason"] == "Mission timed out"
    assert mission["status"]["failure_category"] == "TIMEOUT"
    assert mission["status"]["node_status"]["far"]["state"] == "FAILED"

    def cancel_sent():
        messages = recorder.for_robot(robot, "instantActions")
        return any(a["actionType"] == "cancelOrder" for m in messages for a in m["actions"])

    wait_for(cancel_sent, message="cancelOrder after the timeout")
    robot_status = wait_robot(api, robot, state="IDLE")
    assert robot_status["status"]["pose"]["x"] < 400  # it stopped instead of driving on


def test_move_nodes_distance_and_rotation(api, simulator, unique):
    robot = unique("mover")
    simulator(f"{robot},1,1,{math.pi / 4}")
    create_robot(api, robot)
    name = unique("m")
    tree = [
        {"name": "forward", "move": {"distance": 1}},
        {"name": "turn", "move": {"rotation": math.pi / 4}},
    ]
    post_mission(api, name, robot, tree)
    assert wait_mission(api, name)["status"]["state"] == "COMPLETED"
    wait_robot(api, robot, state="IDLE")
    pose = wait_for(
        lambda: (p := get(api, "robot", robot)["status"]["pose"])["theta"] > 1.2 and p, message="robot turned"
    )
    assert math.isclose(pose["x"], 1.71, abs_tol=0.15)
    assert math.isclose(pose["y"], 1.71, abs_tol=0.15)
    assert math.isclose(pose["theta"], math.pi / 2, abs_tol=0.1)


def test_route_then_actions_flat_tree(api, unique, recorder, simulated_robot):
    robot = simulated_robot("worker")
    name = unique("m")
    tree = [route("go", (1, 1)), action("work", should_fail=0, time=0.2), route("back", (0, 0))]
    mission = wait_mission(api, post_mission(api, name, robot, tree)["name"])
    assert mission["status"]["state"] == "COMPLETED"
    assert {k: v["state"] for k, v in mission["status"]["node_status"].items()} == dict.fromkeys(
        ["root", "go", "work", "back"], "COMPLETED"
    )
    action_order = next(o for o in recorder.for_robot(robot, "order") if o["nodes"][0]["actions"])
    parameters = {p["key"]: p["value"] for p in action_order["nodes"][0]["actions"][0]["actionParameters"]}
    assert parameters == {"should_fail": 0, "time": 0.2}  # typed values, not strings


def test_action_failure_fails_mission_with_error(api, unique, simulated_robot):
    robot = simulated_robot("worker")
    name = unique("m")
    tree = [route("go", (1, 0)), action("fail", should_fail=1, time=0.1), route("never", (0, 0))]
    mission = wait_mission(api, post_mission(api, name, robot, tree)["name"])
    status = mission["status"]
    assert status["state"] == "FAILED"
    assert status["node_status"]["fail"]["state"] == "FAILED"
    assert status["node_status"]["fail"]["error_msg"]
    assert status["node_status"]["never"]["state"] == "PENDING"
    assert status["failure_category"] == "ROBOT_APP"


def test_selector_recovers_from_failing_action(api, unique, simulated_robot):
    robot = simulated_robot("worker")
    name = unique("m")
    tree = [
        route("start", (1, 0)),
        composite("pick", "selector"),
        action("try", should_fail=1, time=0.1, parent="pick"),
        route("fallback", (0, 1), parent="pick"),
    ]
    recorder_ = StatusRecorder(api, name)
    mission = wait_mission(api, post_mission(api, name, robot, tree)["name"])
    sequence = recorder_.stop()
    status = mission["status"]
    assert status["state"] == "COMPLETED"
    assert status["node_status"]["try"]["state"] == "FAILED"
    assert status["node_status"]["fallback"]["state"] == "COMPLETED"
    assert status["node_status"]["pick"]["state"] == "COMPLETED"
    assert status["failure_reason"] is None  # no stale reason once the selector recovered
    nodes = [node for state, node in sequence if state == "RUNNING"]
    assert nodes == sorted(nodes) and nodes[-1] == 3


def test_sequence_with_failing_action_fails_and_skips_sibling(api, unique, simulated_robot):
    robot = simulated_robot("worker")
    name = unique("m")
    tree = [
        route("start", (1, 0)),
        composite("seq", "sequence"),
        action("try", should_fail=1, time=0.1, parent="seq"),
        route("after", (0, 1), parent="seq"),
    ]
    status = wait_mission(api, post_mission(api, name, robot, tree)["name"])["status"]
    assert status["state"] == "FAILED"
    assert status["node_status"]["seq"]["state"] == "FAILED"
    assert status["node_status"]["after"]["state"] == "PENDING"


def test_three_layer_tree_with_constants_and_hyphenated_names(api, unique, simulated_robot):
    robot = simulated_robot("worker")
    name = unique("m")
    tree = [
        composite("outer-seq", "sequence"),
        composite("mid-sel", "selector", parent="outer-seq"),
        {"name": "no", "parent": "mid-sel", "constant": {"success": False}},
        composite("inner-seq", "sequence", parent="mid-sel"),
        route("leg-1", (1, 0), parent="inner-seq"),
        route("leg-2", (1, 1), parent="inner-seq"),
        {"name": "yes", "parent": "outer-seq", "constant": {"success": True}},
    ]
    status = wait_mission(api, post_mission(api, name, robot, tree)["name"])["status"]
    assert status["state"] == "COMPLETED"
    states = {k: v["state"] for k, v in status["node_status"].items()}
    assert states == {
        "root": "COMPLETED",
        "outer-seq": "COMPLETED",
        "mid-sel": "COMPLETED",
        "no": "FAILED",
        "inner-seq": "COMPLETED",
        "leg-1": "COMPLETED",
        "leg-2": "COMPLETED",
        "yes": "COMPLETED",
    }


def test_task_status_counts_exactly_reached_waypoints(api, unique, simulated_robot):
    robot = simulated_robot("worker")
    name = unique("m")
    tree = [
        {
            "name": "r",
            "route": {
                "waypoints": [
                    {"x": 1, "y": 0, "map_id": "map", "allowedDeviationXY": 0},
                    {"x": 2, "y": 0, "map_id": "map", "allowedDeviationXY": 0.5},
                    {"x": 3, "y": 0, "map_id": "map", "allowedDeviationXY": 0},
                ]
            },
        }
    ]
    status = wait_mission(api, post_mission(api, name, robot, tree)["name"])["status"]
    assert status["state"] == "COMPLETED"
    assert status["task_status"] == {"r": 2}
