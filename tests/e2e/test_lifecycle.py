"""Reference scenarios `cancel_mission.py`, `update_mission.py`, `delete_robot.py`; deadline, battery."""

from datetime import UTC, datetime, timedelta

import pytest

from missions.models import Mission
from robots.models import Robot
from tests.e2e.helpers import (
    action,
    create_robot,
    get,
    mission_state,
    post_mission,
    route,
    wait_mission,
    wait_mission_where,
    wait_robot,
)
from tests.waiting import wait_for

pytestmark = [pytest.mark.e2e, pytest.mark.django_db(transaction=True)]


def cancel_orders_sent(recorder, robot: str) -> int:
    return sum(
        a["actionType"] == "cancelOrder"
        for m in recorder.for_robot(robot, "instantActions")
        for a in m["actions"]
    )


def test_cancel_and_delete_queued_missions(api, unique, simulated_robot):
    robot = simulated_robot("busy")
    first, canceled, deleted, last = (unique(n) for n in ("first", "canceled", "deleted", "last"))
    post_mission(api, first, robot, [route("r", (5, 0))])
    post_mission(api, canceled, robot, [route("r", (0, 0))])
    post_mission(api, deleted, robot, [route("r", (0, 0))])
    post_mission(api, last, robot, [route("r", (1, 1))])
    assert api.post(f"/mission/{canceled}/cancel").json() == {
        "detail": f"Mission {canceled} will be canceled."
    }
    assert get(api, "mission", canceled)["status"]["state"] == "CANCELED"
    assert api.delete(f"/mission/{deleted}").json() == {"detail": f"{deleted} is PENDING_DELETE"}
    assert not Mission.objects.filter(name=deleted).exists()
    assert wait_mission(api, first)["status"]["state"] == "COMPLETED"
    assert wait_mission(api, last)["status"]["state"] == "COMPLETED"
    status = get(api, "mission", canceled)["status"]
    assert status["start_timestamp"] is None and status["failure_category"] == "CANCELED"


def test_cancel_running_mission_sends_cancel_order_then_next_mission_runs(
    api, unique, recorder, simulated_robot
):
    robot = simulated_robot("busy")
    running, following = unique("running"), unique("next")
    post_mission(api, running, robot, [route("0", (300, 0)), route("1", (0, 0))])
    post_mission(api, following, robot, [route("r", (0, 1))])
    wait_mission(api, running, {"RUNNING"})
    wait_for(lambda: get(api, "robot", robot)["status"]["pose"]["x"] > 0.5, message="robot moving")
    assert api.post(f"/mission/{running}/cancel").status_code == 200
    status = wait_mission(api, running)["status"]
    assert status["state"] == "CANCELED"
    assert status["node_status"]["0"]["state"] == "CANCELED"
    assert status["node_status"]["1"]["state"] == "PENDING"
    assert status["failure_category"] == "CANCELED"
    assert cancel_orders_sent(recorder, robot) >= 1
    assert wait_mission(api, following)["status"]["state"] == "COMPLETED"
    response = api.post(f"/mission/{running}/cancel")
    assert response.status_code == 400
    assert response.json()["error_code"] == "USAGE"


def test_delete_running_mission_cancels_and_removes_it(api, unique, recorder, simulated_robot):
    robot = simulated_robot("busy")
    name = unique("m")
    post_mission(api, name, robot, [route("r", (300, 0))])
    wait_mission(api, name, {"RUNNING"})
    assert api.delete(f"/mission/{name}").status_code == 200
    assert get(api, "mission", name)["lifecycle"] == "PENDING_DELETE"
    wait_for(lambda: not Mission.objects.filter(name=name).exists(), message="mission removed")
    assert cancel_orders_sent(recorder, robot) >= 1
    wait_robot(api, robot, state="IDLE")


def test_delete_and_cancel_completed_mission(api, unique, simulated_robot):
    robot = simulated_robot("quick")
    done, removed = unique("done"), unique("removed")
    post_mission(api, done, robot, [route("r", (1, 0))])
    post_mission(api, removed, robot, [route("r", (0, 0))])
    wait_mission(api, removed)
    response = api.post(f"/mission/{done}/cancel")
    assert response.status_code == 400
    assert response.json() == {
        "message": f"Completed mission {done} can't be canceled.",
        "error_code": "USAGE",
    }
    assert api.delete(f"/mission/{removed}").status_code == 200
    assert not Mission.objects.filter(name=removed).exists()


def test_update_pending_mission_uses_new_waypoints(api, unique, recorder, simulated_robot):
    robot = simulated_robot("upd")
    blocker, name = unique("blocker"), unique("m")
    post_mission(api, blocker, robot, [route("r", (3, 0))])
    post_mission(api, name, robot, [route("r", (1, 1))])
    body = {"r": {"waypoints": [{"x": 2, "y": 2, "theta": 0, "map_id": "map"}]}}
    assert api.post(f"/mission/{name}/update", body, format="json").status_code == 200
    assert wait_mission(api, name)["status"]["state"] == "COMPLETED"
    destination = next(o for o in recorder.for_robot(robot, "order") if o["orderId"].startswith(name))
    assert (
        destination["nodes"][-1]["nodePosition"] | {"x": 2, "y": 2}
        == destination["nodes"][-1]["nodePosition"]
    )


def test_update_running_route_cancels_stale_order_and_sends_new_one(api, unique, recorder, simulated_robot):
    robot = simulated_robot("upd")
    name = unique("m")
    post_mission(api, name, robot, [route("r", (300, 0))])
    wait_mission(api, name, {"RUNNING"})
    wait_for(lambda: recorder.for_robot(robot, "order"), message="first order")
    body = {"r": {"waypoints": [{"x": 1, "y": 2, "theta": 0, "map_id": "map"}]}}
    assert api.post(f"/mission/{name}/update", body, format="json").status_code == 200
    status = wait_mission(api, name)["status"]
    assert status["state"] == "COMPLETED"
    order_ids = [o["orderId"] for o in recorder.for_robot(robot, "order")]
    assert len(set(order_ids)) == 2  # the stale order was never resent after the update
    last = next(o for o in recorder.for_robot(robot, "order") if o["orderId"] == order_ids[-1])
    assert last["nodes"][-1]["nodePosition"]["x"] == 1
    assert cancel_orders_sent(recorder, robot) >= 1


def test_update_completed_mission_is_rejected(api, unique, simulated_robot):
    robot = simulated_robot("upd")
    name = unique("m")
    post_mission(api, name, robot, [route("r", (1, 0))])
    wait_mission(api, name)
    body = {"r": {"waypoints": [{"x": 2, "y": 2}]}}
    response = api.post(f"/mission/{name}/update", body, format="json")
    assert response.status_code == 400


def test_delete_idle_robot_removes_it(api, unique, simulated_robot):
    robot = simulated_robot("gone")
    wait_robot(api, robot, online=True)
    assert api.delete(f"/robot/{robot}").json() == {"detail": f"{robot} is PENDING_DELETE"}
    wait_for(lambda: not Robot.objects.filter(name=robot).exists(), message="robot removed")


def test_delete_robot_on_task_fails_its_mission(api, unique, simulated_robot):
    robot = simulated_robot("gone")
    name, queued = unique("m"), unique("queued")
    post_mission(api, name, robot, [route("r", (300, 0))])
    post_mission(api, queued, robot, [route("r", (0, 0))])
    wait_mission(api, name, {"RUNNING"})
    assert api.delete(f"/robot/{robot}").status_code == 200
    status = wait_mission(api, name)["status"]
    assert status["state"] == "FAILED"
    assert status["failure_category"] == "ROBOT_APP"
    wait_for(lambda: not Robot.objects.filter(name=robot).exists(), message="robot removed")
    assert mission_state(api, queued) == "PENDING"  # reference: queued missions stay


def test_pending_mission_past_deadline_never_starts(api, unique, recorder, simulated_robot):
    robot = simulated_robot("dl")
    blocker, name = unique("blocker"), unique("m")
    post_mission(api, blocker, robot, [route("r", (15, 0))])
    deadline = (datetime.now(UTC) + timedelta(seconds=0.5)).isoformat()
    post_mission(api, name, robot, [route("r", (0, 0))], deadline=deadline)
    status = wait_mission(api, name)["status"]
    assert status["state"] == "FAILED"
    assert status["failure_category"] == "DEADLINE"
    assert status["start_timestamp"] is None
    assert wait_mission(api, blocker)["status"]["state"] == "COMPLETED"


def test_running_mission_past_deadline_fails_and_robot_stops(api, unique, recorder, simulated_robot):
    robot = simulated_robot("dl")
    name = unique("m")
    deadline = (datetime.now(UTC) + timedelta(seconds=2)).isoformat()
    post_mission(api, name, robot, [route("r", (500, 0))], deadline=deadline)
    status = wait_mission(api, name)["status"]
    assert status["state"] == "FAILED"
    assert status["failure_category"] == "DEADLINE"
    wait_for(lambda: cancel_orders_sent(recorder, robot), message="cancelOrder after the deadline")


def test_critical_battery_holds_missions_until_it_recovers(api, simulator, unique):
    robot = unique("low")
    simulator(f"{robot},0,0,0,map,0,5")  # battery 5 %
    create_robot(api, robot, battery={"critical_level": 10})
    wait_robot(api, robot, online=True)
    name = unique("m")
    post_mission(api, name, robot, [route("r", (1, 0))])
    mission = wait_mission_where(api, name, lambda status: bool(status.get("waiting_reason")))
    assert mission["status"]["state"] == "PENDING"
    assert "critical" in mission["status"]["waiting_reason"]
    assert api.put(f"/robot/{robot}", {"battery": {"critical_level": 2}}, format="json").status_code == 200
    assert wait_mission(api, name)["status"]["state"] == "COMPLETED"


def test_action_that_robot_cannot_do_fails_leaf(api, unique, simulated_robot):
    robot = simulated_robot("strict")
    name = unique("m")
    post_mission(api, name, robot, [action("weird", action_type="fly_to_the_moon")])
    status = wait_mission(api, name)["status"]
    assert status["state"] == "FAILED"
    assert status["node_status"]["weird"]["state"] == "FAILED"
    assert status["failure_reason"]
