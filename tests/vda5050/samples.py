"""Messages with every field of the document set, for round trips and schema checks.

Each builder takes the protocol version: a 3.0.0 message carries what 3.0.0 has (instant action states,
zone sets and requests, ...) and leaves out what it dropped (``zoneSetId``, ``mapDescription`` of nodes,
``localizationParameters``); 3.0.0 instant actions are always NONE-blocking.
"""

from __future__ import annotations

from datetime import UTC, datetime

from vda5050.codec import header_for
from vda5050.models import (
    Action,
    ActionParameter,
    ActionState,
    ActionStatus,
    AgvAction,
    AgvClass,
    AgvGeometry,
    AgvKinematic,
    AgvPosition,
    BatteryState,
    BlockingType,
    BoundingBoxReference,
    ConnectionContent,
    ConnectionState,
    ControlPoint,
    Corridor,
    CorridorRefPoint,
    Edge,
    EdgeState,
    Envelope2d,
    Envelope3d,
    Error,
    ErrorLevel,
    ErrorReference,
    EStop,
    FactsheetActionParameter,
    FactsheetContent,
    Header,
    InfoLevel,
    InfoReference,
    Information,
    InstantActionsContent,
    Load,
    LoadDimensions,
    LoadSet,
    LoadSpecification,
    LocalizationType,
    Map,
    MapStatus,
    MaxArrayLens,
    MaxStringLens,
    NavigationType,
    Network,
    Node,
    NodePosition,
    NodeState,
    OperatingMode,
    OptionalParameter,
    OrderContent,
    OrientationType,
    ParameterSupport,
    PhysicalParameters,
    PolygonPoint,
    ProtocolFeatures,
    ProtocolLimits,
    Request,
    SafetyState,
    StateContent,
    Timing,
    Trajectory,
    TypeSpecification,
    ValueDataType,
    VehicleConfig,
    Velocity,
    VersionInfo,
    VisualizationContent,
    WheelDefinition,
    WheelPosition,
    WheelType,
    ZoneSetState,
)
from vda5050.topics import RobotAddress
from vda5050.versions import MAJOR_3, major_of

SAMPLE_TIME = datetime(2026, 11, 22, 10, 0, 0, 123456, tzinfo=UTC)


def sample_header(version: str, header_id: int = 7) -> Header:
    return header_for(
        RobotAddress("uagv", "RobotCompany", "carter01", version), header_id=header_id, at=SAMPLE_TIME
    )


def _is_3(version: str) -> bool:
    return major_of(version) >= MAJOR_3


def _action(
    action_id: str, blocking_type: BlockingType = BlockingType.HARD, version: str = "2.0.0"
) -> Action:
    return Action(
        action_type="pick",
        action_id=action_id,
        action_description="pick a pallet",
        blocking_type=blocking_type,
        action_parameters=[
            ActionParameter(key="height", value=0.25),
            ActionParameter(key="loadType", value="EPAL"),
            ActionParameter(key="retries", value=3),
            ActionParameter(key="strict", value=True),
            ActionParameter(key="stations", value=["a", "b"]),
            ActionParameter(key="target", value={"x": 1.5, "label": "dock"}),
        ],
        retriable=True if _is_3(version) else None,
    )


def _node_position(x: float, version: str = "2.0.0") -> NodePosition:
    return NodePosition(
        x=x,
        y=2.0,
        theta=1.57,
        allowed_deviation_xy=0.1,
        allowed_deviation_theta=0.2,
        map_id="floor1",
        map_description=None if _is_3(version) else "ground floor",
    )


def _trajectory() -> Trajectory:
    return Trajectory(
        degree=1,
        knot_vector=[0.0, 0.0, 1.0, 1.0],
        control_points=[ControlPoint(x=0.0, y=2.0, weight=1.0), ControlPoint(x=3.0, y=2.0)],
    )


def full_order(version: str = "2.0.0") -> OrderContent:
    return OrderContent(
        order_id="order-1",
        order_update_id=2,
        order_description="to the dock" if _is_3(version) else None,
        zone_set_id=None if _is_3(version) else "zones-1",
        nodes=[
            Node(
                node_id="n0",
                sequence_id=0,
                node_description="start",
                released=True,
                node_position=_node_position(0.0, version),
                actions=[_action("a0", version=version)],
            ),
            Node(
                node_id="n1",
                sequence_id=2,
                released=False,
                node_position=_node_position(3.0, version),
                actions=[],
            ),
        ],
        edges=[
            Edge(
                edge_id="e1",
                sequence_id=1,
                edge_description="aisle",
                released=False,
                start_node_id="n0",
                end_node_id="n1",
                max_speed=1.2,
                max_height=2.0,
                min_height=0.1,
                orientation=0.0,
                orientation_type=OrientationType.TANGENTIAL,
                direction="left",
                rotation_allowed=False,
                max_rotation_speed=0.5,
                length=3.0,
                trajectory=_trajectory(),
                corridor=Corridor(
                    left_width=0.5,
                    right_width=0.4,
                    corridor_ref_point=CorridorRefPoint.CONTOUR,
                    release_required=True if _is_3(version) else None,
                    release_loss_behavior="STOP" if _is_3(version) else None,
                ),
                actions=[_action("a1", version=version)],
            )
        ],
    )


def full_instant_actions(version: str = "2.0.0") -> InstantActionsContent:
    return InstantActionsContent(
        actions=[_action("ia0", BlockingType.NONE if _is_3(version) else BlockingType.HARD)]
    )


def _agv_position(version: str = "2.0.0") -> AgvPosition:
    return AgvPosition(
        x=1.0,
        y=2.0,
        theta=-0.5,
        map_id="floor1",
        map_description=None if _is_3(version) else "ground floor",
        position_initialized=True,
        localization_score=0.9,
        deviation_range=0.05,
    )


def full_state(version: str = "2.0.0") -> StateContent:
    is_3 = _is_3(version)
    return StateContent(
        maps=[Map(map_id="floor1", map_version="3", map_description="ground", map_status=MapStatus.ENABLED)],
        order_id="order-1",
        order_update_id=2,
        zone_set_id=None if is_3 else "zones-1",
        last_node_id="n0",
        last_node_sequence_id=0,
        driving=True,
        paused=False,
        new_base_request=True,
        distance_since_last_node=0.7,
        operating_mode=OperatingMode.AUTOMATIC,
        node_states=[
            NodeState(
                node_id="n1",
                sequence_id=2,
                node_description="end",
                released=True,
                node_position=_node_position(3.0, version),
            )
        ],
        edge_states=[
            EdgeState(
                edge_id="e1", sequence_id=1, edge_description="aisle", released=True, trajectory=_trajectory()
            )
        ],
        agv_position=_agv_position(version),
        velocity=Velocity(vx=0.5, vy=0.0, omega=0.1),
        loads=[
            Load(
                load_id="L1",
                load_type="EPAL",
                load_position="front",
                bounding_box_reference=BoundingBoxReference(x=0.0, y=0.0, z=0.2, theta=0.0),
                load_dimensions=LoadDimensions(length=1.2, width=0.8, height=1.0),
                weight=300.0,
            )
        ],
        action_states=[
            ActionState(
                action_id="a0",
                action_type="pick",
                action_description="pick a pallet",
                action_status=ActionStatus.FINISHED,
                result_description="ok",
            ),
            ActionState(action_id="a1", action_status=ActionStatus.PAUSED),
        ],
        instant_action_states=[
            ActionState(
                action_id="ia0",
                action_type="startPause",
                action_description="pause",
                action_status=ActionStatus.RETRIABLE,
                result_description="brakes",
            )
        ]
        if is_3
        else None,
        zone_action_states=[
            ActionState(
                action_id="za0",
                action_type="startCharging",
                action_description="charge in zone",
                action_status=ActionStatus.RUNNING,
                result_description="charging",
            )
        ]
        if is_3
        else None,
        zone_sets=[ZoneSetState(map_id="floor1", zone_set_id="zs1", zone_set_status=MapStatus.ENABLED)]
        if is_3
        else None,
        zone_requests=[
            Request(
                request_id="r1",
                request_type="ACCESS",
                request_status="REQUESTED",
                zone_id="z1",
                zone_set_id="zs1",
            )
        ]
        if is_3
        else None,
        edge_requests=[
            Request(
                request_id="r2",
                request_type="CORRIDOR",
                request_status="GRANTED",
                edge_id="e1",
                sequence_id=1,
            )
        ]
        if is_3
        else None,
        battery_state=BatteryState(
            battery_charge=80.0,
            battery_voltage=48.1,
            battery_current=-2.5 if is_3 else None,
            battery_health=97.0,
            charging=False,
            reach=1200.0,
        ),
        errors=[
            Error(
                error_type="orderError",
                error_references=[ErrorReference(reference_key="orderId", reference_value="order-1")],
                error_description="lift too high",
                error_hint="lower the lift",
                error_level=ErrorLevel.CRITICAL if is_3 else ErrorLevel.WARNING,
            )
        ],
        information=[
            Information(
                info_type="user_info",
                info_references=[InfoReference(reference_key="actionId", reference_value="a0")],
                info_description="{}",
                info_level=InfoLevel.INFO,
            )
        ],
        safety_state=SafetyState(e_stop=EStop.NONE, field_violation=False),
    )


def full_connection(version: str = "2.0.0") -> ConnectionContent:
    return ConnectionContent(connection_state=ConnectionState.CONNECTIONBROKEN)


def full_visualization(version: str = "2.0.0") -> VisualizationContent:
    return VisualizationContent(
        agv_position=_agv_position(version),
        velocity=Velocity(vx=0.5, vy=0.1, omega=0.0),
        reference_state_header_id=6 if _is_3(version) else None,
    )


def full_factsheet(version: str = "2.0.0") -> FactsheetContent:
    is_3 = _is_3(version)
    return FactsheetContent(
        type_specification=TypeSpecification(
            series_name="carter",
            series_description="test robot",
            agv_kinematic=AgvKinematic.DIFF,
            agv_class=AgvClass.CARRIER,
            max_load_mass=100.0,
            localization_types=[LocalizationType.NATURAL, LocalizationType.REFLECTOR],
            navigation_types=[NavigationType.AUTONOMOUS],
        ),
        physical_parameters=PhysicalParameters(
            speed_min=0.01,
            speed_max=1.0,
            angular_speed_min=0.01,
            angular_speed_max=1.5,
            acceleration_max=0.5,
            deceleration_max=0.8,
            height_min=0.3,
            height_max=0.5,
            width=0.6,
            length=0.9,
        ),
        protocol_limits=ProtocolLimits(
            max_string_lens=MaxStringLens(
                msg_len=100000,
                topic_serial_len=32,
                topic_elem_len=32,
                id_len=64,
                id_numerical_only=False,
                enum_len=None if is_3 else 32,
                load_id_len=32,
            ),
            max_array_lens=MaxArrayLens(
                order_nodes=100,
                order_edges=99,
                node_actions=5,
                edge_actions=5,
                actions_actions_parameters=10,
                instant_actions=5,
                trajectory_knot_vector=20,
                trajectory_control_points=16,
                state_node_states=100,
                state_edge_states=99,
                state_loads=1,
                state_action_states=50,
                state_errors=20,
                state_information=20,
                error_error_references=5,
                information_info_references=5,
            ),
            timing=Timing(
                min_order_interval=0.5,
                min_state_interval=0.1,
                default_state_interval=30.0,
                visualization_interval=1.0,
            ),
        ),
        protocol_features=ProtocolFeatures(
            optional_parameters=[
                OptionalParameter(
                    parameter="order.nodes.nodePosition.allowedDeviationTheta",
                    support=ParameterSupport.SUPPORTED,
                    description="used when set",
                )
            ],
            agv_actions=[
                AgvAction(
                    action_type="pick",
                    action_description="pick a load",
                    action_scopes=["NODE", "EDGE"],
                    action_parameters=[
                        FactsheetActionParameter(
                            key="height",
                            value_data_type=ValueDataType.NUMBER,
                            description="m",
                            is_optional=True,
                        )
                    ],
                    result_description="load id",
                    blocking_types=[BlockingType.SOFT, BlockingType.HARD],
                    pause_allowed=True if is_3 else None,
                    cancel_allowed=False if is_3 else None,
                )
            ],
        ),
        agv_geometry=AgvGeometry(
            wheel_definitions=[
                WheelDefinition(
                    type=WheelType.DRIVE,
                    is_active_driven=True,
                    is_active_steered=False,
                    position=WheelPosition(x=0.0, y=0.25, theta=0.0),
                    diameter=0.2,
                    width=0.05,
                    center_displacement=0.0,
                    constraints="none",
                )
            ],
            envelopes2d=[
                Envelope2d(
                    set="default",
                    polygon_points=[
                        PolygonPoint(x=0.0, y=0.0),
                        PolygonPoint(x=1.0, y=0.0),
                        PolygonPoint(x=0.0, y=1.0),
                    ],
                    description="footprint",
                )
            ],
            envelopes3d=[
                Envelope3d(set="default", format="DXF", data={"a": 1}, url="ftp://x/y", description="hull")
            ],
        ),
        load_specification=LoadSpecification(
            load_positions=["front"],
            load_sets=[
                LoadSet(
                    set_name="DEFAULT",
                    load_type="EPAL",
                    load_positions=["front"],
                    bounding_box_reference=BoundingBoxReference(x=0.0, y=0.0, z=0.1, theta=0.0),
                    load_dimensions=LoadDimensions(length=1.2, width=0.8, height=0.15),
                    max_weight=100.0,
                    min_loadhandling_height=0.0,
                    max_loadhandling_height=0.2,
                    min_loadhandling_depth=0.0,
                    max_loadhandling_depth=1.2,
                    min_loadhandling_tilt=0.0,
                    max_loadhandling_tilt=0.1,
                    agv_speed_limit=0.8,
                    agv_acceleration_limit=0.4,
                    agv_deceleration_limit=0.6,
                    pick_time=5.0,
                    drop_time=4.0,
                    description="euro pallet",
                )
            ],
        ),
        localization_parameters=None if is_3 else {},
        vehicle_config=VehicleConfig(
            versions=[VersionInfo(key="softwareVersion", value="v1.03.2")],
            network=Network(
                dns_servers=["10.0.0.1"],
                ntp_servers=["10.0.0.2"],
                local_ip_address="10.0.0.10",
                netmask="255.255.255.0",
                default_gateway="10.0.0.1",
            ),
        ),
    )


# topic name -> builder of the full content of that message in a version
FULL_CONTENTS = {
    "order": full_order,
    "instantActions": full_instant_actions,
    "state": full_state,
    "connection": full_connection,
    "visualization": full_visualization,
    "factsheet": full_factsheet,
}
