"""The battery: drained by driving (not by standing), charged between startCharging (a node or an instant
action) and stopCharging or a full battery, as the state's batteryState reports; the factsheet lists the
charging actions only for robots that can charge."""

from __future__ import annotations

import shlex
from pathlib import Path

import orjson
import pytest

from simulator.cli import build_parser, robot_configs, settings_from
from simulator.config import DEFAULT_BATTERY_DRAIN, SimulationSettings, parse_robot_spec
from tests.simulator.conftest import RobotHarness, action, route
from vda5050.models import ActionStatus
from vda5050.topics import Topic

# Spec fields: name,x,y,theta,map_id,failure_period,battery,...,stack,battery_drain,charge_rate
FULL_ROBOT = "carter01,0,0,0,map,0,100"
ROOT = Path(__file__).resolve().parents[2]
README_MINIMUM = 30.0  # README, "Stations: charging and parking": carter01's recommended minimum


def charge(h: RobotHarness) -> float:
    return h.state.battery_state.battery_charge


def test_driving_drains_the_battery_by_the_metre_and_standing_does_not():
    h = RobotHarness(FULL_ROBOT + ",,,,,,0.5")
    h.run(60)
    assert charge(h) == 100.0  # idle for a minute

    h.send_order(route((10.0, 0.0), (10.0, 6.0)))
    h.run_until(lambda state: not state.node_states and not state.driving)

    assert charge(h) == pytest.approx(100.0 - 16 * 0.5)
    assert h.state.battery_state.charging is False


def test_by_default_the_battery_does_not_drain_while_robots_cannot_yet_charge_by_themselves():
    assert SimulationSettings().battery_drain == DEFAULT_BATTERY_DRAIN == 0.0
    h = RobotHarness(FULL_ROBOT)
    h.send_order(route((10.0, 0.0), (10.0, 6.0)))
    h.run_until(lambda state: not state.node_states and not state.driving)

    assert charge(h) == 100.0


def test_the_battery_never_falls_below_empty():
    h = RobotHarness("carter01,0,0,0,map,0,3,,,,,,1")
    h.send_order(route((10.0, 0.0)))
    h.run_until(lambda state: not state.node_states and not state.driving)

    assert charge(h) == 0.0


def test_start_charging_at_the_end_of_an_order_charges_until_full():
    h = RobotHarness("carter01,0,0,0,map,0,20,,,,,,0.5,2")
    order = route((4.0, 0.0))
    order.nodes[-1].actions.append(action("startCharging", "charge-1"))
    h.send_order(order)
    h.run_until(lambda state: state.battery_state.charging)
    assert h.action_state("charge-1").action_status == ActionStatus.FINISHED
    at_charger = charge(h)
    assert at_charger == pytest.approx(18.0)

    h.run(5)
    assert charge(h) == pytest.approx(at_charger + 10, abs=0.6)
    h.run(60)
    assert (charge(h), h.state.battery_state.charging) == (100.0, False)  # full: stops by itself
    charging_flags = [state.battery_state.charging for state in h.states()]
    assert charging_flags[-1] is False and True in charging_flags


def test_stop_charging_as_an_instant_action_stops_it_and_driving_off_does_too():
    h = RobotHarness("carter01,0,0,0,map,0,20,,,,,,0.5,2")
    h.send_actions(action("startCharging", "start"))
    assert h.state.battery_state.charging is True
    h.run(3)
    h.send_actions(action("stopCharging", "stop"))
    stopped_at = charge(h)

    assert h.state.battery_state.charging is False
    assert stopped_at == pytest.approx(26.0, abs=0.6)
    assert h.action_state("stop").action_status == ActionStatus.FINISHED
    h.run(5)
    assert charge(h) == stopped_at

    h.send_actions(action("startCharging", "again"))
    h.send_order(route((2.0, 0.0)))
    h.tick()
    assert h.state.battery_state.charging is False


@pytest.mark.parametrize(
    ("spec", "settings", "lists_charging"),
    [
        ("carter01,0,0", {}, True),
        ("carter01,0,0,0,map,0,20,,,,,,,0", {}, False),
        ("carter01,0,0", {"charge_rate": 0.0}, False),
        ("carter01,0,0,0,map,0,20,,,,,,,1", {"charge_rate": 0.0}, True),
    ],
)
def test_the_factsheet_lists_the_charging_actions_of_robots_that_charge(spec, settings, lists_charging):
    h = RobotHarness(spec, **settings)

    (message,) = [m for m in h.send_actions(action("factsheetRequest", "fr")) if m.kind == Topic.FACTSHEET]
    actions = {a["actionType"] for a in orjson.loads(message.payload)["protocolFeatures"]["agvActions"]}

    assert ({"startCharging", "stopCharging"} <= actions) is lists_charging
    assert not ({"startCharging", "stopCharging"} & actions) or lists_charging


def test_a_robot_that_cannot_charge_fails_start_charging():
    h = RobotHarness("carter01,0,0,0,map,0,20,,,,,,,0")
    h.send_actions(action("startCharging", "start"))
    order = route((1.0, 0.0))
    order.nodes[-1].actions.append(action("startCharging", "node-start"))

    assert h.action_state("start").action_status == ActionStatus.FAILED
    h.send_order(order)
    h.run(5)
    assert h.action_state("node-start").action_status == ActionStatus.FAILED
    assert h.state.battery_state.charging is False


def test_the_charge_and_rates_come_from_the_spec_or_the_command_line():
    args = build_parser().parse_args(
        ["--robots", "a,0,0", "b,0,0,0,map,0,50,,,,,,1.5,3", "--battery", "80", "--charge_rate", "4"]
    )
    a, b = robot_configs(args)
    settings = settings_from(args)

    assert (a.battery_drain, a.charge_rate, b.battery_drain, b.charge_rate) == (None, None, 1.5, 3.0)
    assert (a.battery_at_start(settings), b.battery_at_start(settings)) == (80.0, 50.0)
    assert (a.battery_rates(settings), b.battery_rates(settings)) == ((0.0, 4.0), (1.5, 3.0))
    with pytest.raises(ValueError, match="--battery must be a percentage"):
        settings_from(build_parser().parse_args(["--battery", "101"]))
    with pytest.raises(ValueError, match="battery_drain and charge_rate"):
        parse_robot_spec("c,0,0,0,map,0,50,,,,,,-1")


def test_the_robots_of_make_run_drain_from_a_high_charge_tens_of_missions_before_their_minimum():
    """deploy/Procfile's simulator (`make run`): batteries that drain, so that a robot goes to charge by
    itself once a charger exists, but slowly enough that a new user's first missions strand no robot."""
    line = next(
        line
        for line in (ROOT / "deploy" / "Procfile").read_text().splitlines()
        if line.startswith("simulator:")
    )
    argv = shlex.split(line.split(":", 1)[1])
    args = build_parser().parse_args(argv[argv.index("simulator") + 1 :])
    settings = settings_from(args)

    for config in robot_configs(args):
        drain, charge_rate = config.battery_rates(settings)
        start = config.battery_at_start(settings)
        assert drain > 0 and charge_rate > 0 and start >= 80
        # Metres driven before the README's minimum of 30 %: the README's missions drive about 10 m each.
        assert 300 <= (start - README_MINIMUM) / drain <= 2000
