"""One simulated VDA 5050 robot as a pure state machine: messages and time in, messages out.

No I/O: the runner feeds received payloads and the clock (``now``, UNIX seconds) into ``receive`` and
``tick`` and publishes what they return, so tests drive a robot with a fake clock.

The robot is as strict as a real AGV: ``simulator.acceptance`` decides which orders it takes. Order
actions run one at a time with the robot standing still. A FATAL error (a failed action, a simulated
failure) makes the robot abandon its order as ``cancelOrder`` would: it stops, drops the remaining nodes
and edges and fails the actions not done; the error stays until the next order is accepted.

``SimulatedRobot`` composes its parts and runs the order: ``CurrentOrder`` (what it holds), ``Drive``
(how it moves), ``RobotMaps``, ``ErrorReport``, ``Outbox`` (what goes out when), ``OrderAcceptance`` and
``InstantActionHandler``.
"""

from __future__ import annotations

import math

from simulator.acceptance import OrderAcceptance
from simulator.actions import (
    ActionRun,
    ClearLoads,
    Effect,
    SetCharging,
    SetLoad,
    SetMap,
    UnusableAction,
    plan_order_action,
)
from simulator.battery import Battery
from simulator.config import DEFAULT_INTERFACE_NAME, RobotConfig, SimulationSettings
from simulator.errors import ACTION_ERROR, ErrorReport
from simulator.instant import InstantActionHandler
from simulator.maps import RobotMaps
from simulator.motion import Drive, VehiclePose, jump_to, normalize_angle, step_towards, target_of
from simulator.orders import CurrentOrder
from simulator.outbox import Outbox, Publication
from simulator.zones import RobotZones
from vda5050.maps import has_maps
from vda5050.models import (
    ActionStatus,
    AgvPosition,
    BatteryState,
    ConnectionState,
    ErrorLevel,
    EStop,
    Load,
    OperatingMode,
    SafetyState,
    StateContent,
    VisualizationContent,
)
from vda5050.topics import RobotAddress, Topic
from vda5050.versions import MAJOR_3, major_of

ACTION_FAILURE = "Action failure"  # Isaac Mission Dispatch shows this description as the failure reason


class SimulatedRobot:
    def __init__(
        self,
        config: RobotConfig,
        settings: SimulationSettings,
        *,
        now: float,
        topic_address: RobotAddress | None = None,
    ) -> None:
        """``topic_address`` gives the topic levels (default ``uagv/v<major>/<manufacturer>/<serial>``)."""
        self.config = config
        self.settings = settings
        self.version = config.vda_version or settings.version
        self.is_3 = major_of(self.version) >= MAJOR_3
        self.has_maps = has_maps(self.version)
        # who the robot is in message headers (the interface name is not part of a header)
        self.address = RobotAddress(DEFAULT_INTERFACE_NAME, config.manufacturer, config.serial, self.version)
        self.topic_address = topic_address or self.address
        outbox = Outbox(
            config,
            settings,
            version=self.version,
            address=self.address,
            topic_address=self.topic_address,
            now=now,
        )
        errors = ErrorReport(outbox, is_3=self.is_3)
        drive = Drive(VehiclePose(config.x, config.y, normalize_angle(config.theta)), settings, outbox)
        maps = RobotMaps(
            config.map_id, has_maps=self.has_maps, settings=settings, errors=errors, outbox=outbox
        )
        order = CurrentOrder(outbox)
        zones = RobotZones(serial=config.serial, errors=errors, outbox=outbox)
        drain, charge_rate = config.battery_rates(settings)
        battery = Battery(
            charge=config.battery_at_start(settings), drain_per_metre=drain, charge_rate=charge_rate
        )
        self._outbox = outbox
        self._battery = battery
        self._errors = errors
        self._drive = drive
        self._maps = maps
        self._order = order
        self._zones = zones
        self._loads: list[Load] = []
        self._acceptance = OrderAcceptance(
            config, settings, self.address, order=order, maps=maps, drive=drive, errors=errors
        )
        self._instant_actions = InstantActionHandler(
            config,
            self.address,
            is_3=self.is_3,
            has_maps=self.has_maps,
            order=order,
            maps=maps,
            zones=zones,
            drive=drive,
            errors=errors,
            outbox=outbox,
            battery=battery,
        )

    # --- the runner's interface --------------------------------------------------------------------

    def topic(self, kind: Topic) -> str:
        return self._outbox.topic(kind)

    def subscriptions(self) -> list[str]:
        zones = (Topic.ZONE_SET, Topic.RESPONSES) if self.is_3 else ()
        return [self.topic(kind) for kind in (Topic.ORDER, Topic.INSTANT_ACTIONS, *zones)]

    def last_will(self, now: float) -> Publication:
        """Registered with the broker at connect time, sent by it if the connection breaks."""
        return self._outbox.connection(ConnectionState.CONNECTIONBROKEN, now)

    def connected(self, now: float) -> list[Publication]:
        """ONLINE, then the factsheet (retained, so masters find it) and a state."""
        self._outbox.factsheet_requested = True
        self._outbox.state_changed = True
        return [self._outbox.connection(ConnectionState.ONLINE, now), *self._due_messages(now)]

    def going_offline(self, now: float) -> Publication:
        return self._outbox.connection(ConnectionState.OFFLINE, now)

    def receive(self, kind: Topic, payload: bytes, now: float) -> list[Publication]:
        if kind == Topic.ORDER:
            self._acceptance.receive(payload)
        elif kind == Topic.INSTANT_ACTIONS:
            self._instant_actions.receive(payload, now)
        elif kind == Topic.ZONE_SET and self.is_3:
            self._zones.receive_zone_set(payload)
        elif kind == Topic.RESPONSES and self.is_3:
            self._zones.receive_responses(payload)
        else:
            return []
        self._progress(now, may_move=self.settings.completes_instantly)
        return self._due_messages(now)

    def tick(self, now: float) -> list[Publication]:
        """One motion step and whatever is due: a state on any change or every state_period."""
        self.advance(now)
        return self._due_messages(now)

    def advance(self, now: float) -> None:
        """One motion step without publishing (while disconnected: the robot keeps working)."""
        self._progress(now, may_move=True)

    def state_content(self) -> StateContent:
        """What the next state message will say (without header)."""
        order = self._order
        drive = self._drive
        runs = order.runs.values()
        return StateContent(
            maps=self._maps.report(),
            order_id=order.order_id,
            order_update_id=order.order_update_id,
            zone_set_id=order.zone_set_id,
            zone_sets=self._zones.report() if self.is_3 else None,
            zone_requests=self._zones.requests() if self.is_3 else None,
            last_node_id=order.last_node_id,
            last_node_sequence_id=order.last_node_sequence_id,
            driving=drive.driving,
            paused=drive.paused,
            new_base_request=order.new_base_request(),
            operating_mode=OperatingMode.AUTOMATIC,
            node_states=order.node_states(),
            edge_states=order.edge_states(),
            agv_position=self._agv_position(),
            velocity=drive.velocity_model(),
            loads=list(self._loads),
            action_states=[run.to_state() for run in runs if not (self.is_3 and run.instant)],
            instant_action_states=[run.to_state() for run in runs if run.instant] if self.is_3 else None,
            battery_state=BatteryState(battery_charge=self._battery.charge, charging=self._battery.charging),
            errors=list(self._errors.errors),
            information=[],
            safety_state=SafetyState(e_stop=EStop.NONE, field_violation=False),
        )

    # --- running the order -------------------------------------------------------------------------

    def _progress(self, now: float, *, may_move: bool) -> None:
        """Run actions and drive until blocked: an action still running, paused, or (at most) one
        motion step done; instant mode goes on until the decision point."""
        instant = self.settings.completes_instantly
        order = self._order
        drive = self._drive
        self._maps.finish_downloads(now)
        if self._battery.charging and self._battery.charge_until(now):
            self._outbox.state_changed = True  # full: charging ended
        start = drive.pose
        moved = False
        while True:
            if order.running is not None:
                run = order.runs[order.running]
                if run.ends_at is None or now < run.ends_at:
                    break
                order.running = None
                self._finish(run, now)
                continue
            if drive.paused:
                break
            if order.queue:
                self._start(order.queue.popleft(), now)
                continue
            if not order.nodes or not order.nodes[0].released or order.halted():
                break
            edge = order.edges[0] if order.edges else None
            if edge is not None and edge.sequence_id != order.entered_edge:
                order.entered_edge = edge.sequence_id
                order.queue.extend(action.action_id for action in edge.actions)
                continue
            target = target_of(order.nodes[0])
            if target.reached_by(drive.pose):
                order.arrive(order.nodes.pop(0))
                continue
            if drive.teleop or not may_move or (moved and not instant):
                break
            here = (drive.pose.x, drive.pose.y)
            if not self._zones.may_drive(self._maps.map_id, here, (target.x, target.y)):
                break  # at the last node before a RELEASE zone it has no grant for
            if self._battery.charging:  # driving off the charger
                self._battery.stop_charging(now)
            drive.pose = (
                jump_to(drive.pose, target)
                if instant
                else step_towards(drive.pose, target, drive.step_length(edge))
            )
            moved = True
        if may_move:  # a message between two ticks neither starts nor stops driving
            drive.set_motion(start, driving=moved and not instant)
        self._zones.moved((drive.pose.x, drive.pose.y), route_left=bool(order.nodes))
        if moved:
            self._battery.drive(math.hypot(drive.pose.x - start.x, drive.pose.y - start.y))

    def _start(self, action_id: str, now: float) -> None:
        run = self._order.runs.get(action_id)
        if run is None or run.status != ActionStatus.WAITING:
            return
        self._outbox.state_changed = True
        try:
            plan = plan_order_action(
                run.action, self.settings.completes_instantly, can_charge=self._battery.can_charge
            )
        except UnusableAction as exc:
            self._action_failed(run, str(exc))
            return
        run.plan = plan
        run.status = ActionStatus.RUNNING
        run.ends_at = None if plan.duration is None else now + plan.duration
        self._order.running = action_id

    def _finish(self, run: ActionRun, now: float) -> None:
        plan = run.plan
        assert plan is not None  # only started actions run
        self._outbox.state_changed = True
        if plan.fails:
            self._action_failed(run, plan.result)
            return
        for effect in plan.effects:
            self._apply(effect, now)
        run.finish(plan.result)

    def _action_failed(self, run: ActionRun, reason: str) -> None:
        """A node/edge action failed: FATAL, the robot abandons its order."""
        run.fail(reason)
        self._errors.add(
            ACTION_ERROR,
            ACTION_FAILURE,
            ErrorLevel.FATAL,
            [("actionId", run.action.action_id), ("orderId", self._order.order_id)],
        )
        self._order.drop(ACTION_FAILURE)
        self._drive.stop()

    def _apply(self, effect: Effect, now: float) -> None:
        match effect:
            case SetCharging(charging=True):
                self._battery.start_charging(now)
            case SetCharging(charging=False):
                self._battery.stop_charging(now)
            case SetMap(map_id=map_id):
                self._maps.localize_on(map_id)
            case SetLoad(load_id=load_id, load_type=load_type):
                self._loads = [Load(load_id=load_id, load_type=load_type)]
            case ClearLoads():
                self._loads = []

    # --- outgoing messages -------------------------------------------------------------------------

    def _due_messages(self, now: float) -> list[Publication]:
        outbox = self._outbox
        messages = []
        if outbox.factsheet_due():
            messages.append(outbox.factsheet(now))
        if outbox.state_due(now):
            messages.append(outbox.message(Topic.STATE, self.state_content(), now))
        if outbox.visualization_due(now):
            content = VisualizationContent(
                agv_position=self._agv_position(),
                velocity=self._drive.velocity_model(),
                # 3.0: the state this position goes with (the last one sent)
                reference_state_header_id=outbox.last_state_header_id() if self.is_3 else None,
            )
            messages.append(outbox.message(Topic.VISUALIZATION, content, now))
        return messages

    def _agv_position(self) -> AgvPosition:
        pose = self._drive.pose
        return AgvPosition(
            x=pose.x, y=pose.y, theta=pose.theta, map_id=self._maps.map_id, position_initialized=True
        )
