"""Typed VDA 5050 messages (2.0.0, 2.1.0, 3.0.0), in one shape.

Attributes are snake_case; the wire names (camelCase, plus a few irregular ones such as
``allowedDeviationXY`` or the dotted ``maxArrayLens`` keys) are aliases, so camelCase exists only at
the wire boundary. Parsing is tolerant (unknown fields are ignored, optional fields may be missing);
a field is required here when the document or every version's schema requires it for the message.
Fields added in 2.1.0 or 3.0.0 are optional, so one model serves every version. Names are 2.x's (also
for enum values); ``vda5050.versions`` translates to and from 3.0.0's names and structure at the wire.

Every message exists twice: a ``...Content`` model without header (what a sender builds) and the
message model ``Header + Content`` (what is on the wire). ``codec.encode`` stamps the header.
"""

from __future__ import annotations

import math
from enum import StrEnum
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, ConfigDict, Field
from pydantic.alias_generators import to_camel

UINT32_MAX = 2**32 - 1  # the document's headerIds, sequenceIds and orderUpdateIds are uint32
UInt = Annotated[int, Field(ge=0, le=UINT32_MAX)]


class VdaModel(BaseModel):
    """Base of every VDA 5050 object: camelCase aliases, tolerant of unknown fields, no NaN."""

    model_config = ConfigDict(
        alias_generator=to_camel,
        populate_by_name=True,
        extra="ignore",
        allow_inf_nan=False,
    )


# --- enums -----------------------------------------------------------------------------------------


class ActionStatus(StrEnum):
    WAITING = "WAITING"
    INITIALIZING = "INITIALIZING"
    RUNNING = "RUNNING"
    PAUSED = "PAUSED"
    RETRIABLE = "RETRIABLE"  # 3.0: failed, waiting for a retry or skipRetry instant action
    FINISHED = "FINISHED"
    FAILED = "FAILED"


class BlockingType(StrEnum):
    NONE = "NONE"
    SOFT = "SOFT"
    SINGLE = "SINGLE"  # 3.0: driving allowed, no other action in parallel
    HARD = "HARD"


class OrientationType(StrEnum):
    GLOBAL = "GLOBAL"
    TANGENTIAL = "TANGENTIAL"


class CorridorRefPoint(StrEnum):
    KINEMATICCENTER = "KINEMATICCENTER"
    CONTOUR = "CONTOUR"


class MapStatus(StrEnum):
    ENABLED = "ENABLED"
    DISABLED = "DISABLED"


class OperatingMode(StrEnum):
    STARTUP = "STARTUP"  # 3.0
    AUTOMATIC = "AUTOMATIC"
    SEMIAUTOMATIC = "SEMIAUTOMATIC"
    INTERVENED = "INTERVENED"  # 3.0: only cancelOrder is accepted
    MANUAL = "MANUAL"
    SERVICE = "SERVICE"
    TEACHIN = "TEACHIN"  # 3.0 spells it TEACH_IN


class ErrorLevel(StrEnum):
    WARNING = "WARNING"
    URGENT = "URGENT"  # 3.0: still operable, needs attention soon
    CRITICAL = "CRITICAL"  # 3.0: the current order cannot go on; the robot stays operable otherwise
    FATAL = "FATAL"


class ErrorType(StrEnum):
    """Predefined error types we act on, in both spellings (2.x camelCase, 3.0 UPPER_SNAKE)."""

    VALIDATION_ERROR = "validationError"
    NO_ORDER_TO_CANCEL = "noOrderToCancel"
    VALIDATION_FAILURE = "VALIDATION_FAILURE"  # 3.0's validationError
    NO_ORDER_TO_CANCEL_3 = "NO_ORDER_TO_CANCEL"


class InfoLevel(StrEnum):
    INFO = "INFO"
    DEBUG = "DEBUG"


class EStop(StrEnum):
    AUTOACK = "AUTOACK"
    MANUAL = "MANUAL"
    REMOTE = "REMOTE"
    NONE = "NONE"


class ConnectionState(StrEnum):
    ONLINE = "ONLINE"
    OFFLINE = "OFFLINE"
    HIBERNATING = "HIBERNATING"  # 3.0: connected, asleep until stopHibernation
    CONNECTIONBROKEN = "CONNECTIONBROKEN"  # 3.0 spells it CONNECTION_BROKEN


class AgvKinematic(StrEnum):
    """2.x values; 3.0 spells them DIFFERENTIAL, OMNIDIRECTIONAL, THREE_WHEEL and allows others."""

    DIFF = "DIFF"
    OMNI = "OMNI"
    THREEWHEEL = "THREEWHEEL"


class AgvClass(StrEnum):
    FORKLIFT = "FORKLIFT"
    CONVEYOR = "CONVEYOR"
    TUGGER = "TUGGER"
    CARRIER = "CARRIER"


class LocalizationType(StrEnum):
    NATURAL = "NATURAL"
    REFLECTOR = "REFLECTOR"
    RFID = "RFID"
    DMC = "DMC"
    SPOT = "SPOT"
    GRID = "GRID"


class NavigationType(StrEnum):
    PHYSICAL_LINE_GUIDED = "PHYSICAL_LINE_GUIDED"
    VIRTUAL_LINE_GUIDED = "VIRTUAL_LINE_GUIDED"
    AUTONOMOUS = "AUTONOMOUS"


class ParameterSupport(StrEnum):
    SUPPORTED = "SUPPORTED"
    REQUIRED = "REQUIRED"


class ActionScope(StrEnum):
    INSTANT = "INSTANT"
    NODE = "NODE"
    EDGE = "EDGE"
    ZONE = "ZONE"  # 3.0


class ValueDataType(StrEnum):
    BOOL = "BOOL"
    NUMBER = "NUMBER"
    INTEGER = "INTEGER"
    FLOAT = "FLOAT"
    STRING = "STRING"
    OBJECT = "OBJECT"
    ARRAY = "ARRAY"


class WheelType(StrEnum):
    DRIVE = "DRIVE"
    CASTER = "CASTER"
    FIXED = "FIXED"
    MECANUM = "MECANUM"


class ActionType(StrEnum):
    """Predefined action types (2.1.0) plus NVIDIA's teleop pair; vendors may define any other string."""

    START_PAUSE = "startPause"
    STOP_PAUSE = "stopPause"
    START_CHARGING = "startCharging"
    STOP_CHARGING = "stopCharging"
    INIT_POSITION = "initPosition"
    ENABLE_MAP = "enableMap"
    DOWNLOAD_MAP = "downloadMap"
    DELETE_MAP = "deleteMap"
    STATE_REQUEST = "stateRequest"
    FACTSHEET_REQUEST = "factsheetRequest"
    LOG_REPORT = "logReport"
    PICK = "pick"
    DROP = "drop"
    DETECT_OBJECT = "detectObject"
    FINE_POSITIONING = "finePositioning"
    WAIT_FOR_TRIGGER = "waitForTrigger"
    CANCEL_ORDER = "cancelOrder"
    START_TELEOP = "startTeleop"
    STOP_TELEOP = "stopTeleop"
    # 3.0: zone sets (the content itself comes on the zoneSet topic, or by download)
    DOWNLOAD_ZONE_SET = "downloadZoneSet"
    ENABLE_ZONE_SET = "enableZoneSet"
    DELETE_ZONE_SET = "deleteZoneSet"


# --- header ----------------------------------------------------------------------------------------


class MessageHeader(VdaModel):
    """The five flat header fields every message carries (stamped at publish time)."""

    header_id: UInt
    timestamp: str
    version: str
    manufacturer: str
    serial_number: str


class Header(MessageHeader):
    """A header to stamp onto content (``codec.encode``); immutable, unlike the messages themselves."""

    model_config = ConfigDict(frozen=True)


# --- order -----------------------------------------------------------------------------------------


def _is_json(value: Any) -> bool:
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, list):
        return all(_is_json(item) for item in value)
    if isinstance(value, dict):
        return all(isinstance(key, str) and _is_json(item) for key, item in value.items())
    return value is None or isinstance(value, bool | int | str)


def _require_json_value(value: Any) -> Any:
    """The schema allows array, boolean, number, string or object; NaN/Infinity are not JSON."""
    if value is None or not _is_json(value):
        raise ValueError("must be an array, boolean, number, string or object of finite JSON values")
    return value


# Any (not a union) so a value keeps its JSON type: True stays bool, 1 stays int, "1" stays str.
ActionParameterValue = Annotated[Any, AfterValidator(_require_json_value)]


class ActionParameter(VdaModel):
    key: str
    value: ActionParameterValue


class Action(VdaModel):
    action_type: str
    action_id: str
    action_description: str | None = None
    blocking_type: BlockingType
    action_parameters: list[ActionParameter] | None = None
    retriable: bool | None = None  # 3.0


class NodePosition(VdaModel):
    x: float
    y: float
    theta: float | None = None
    allowed_deviation_xy: float | None = Field(default=None, alias="allowedDeviationXY")
    allowed_deviation_theta: float | None = None
    map_id: str
    map_description: str | None = None


class Node(VdaModel):
    node_id: str
    sequence_id: UInt
    node_description: str | None = None
    released: bool
    node_position: NodePosition | None = None
    actions: list[Action]


class ControlPoint(VdaModel):
    x: float
    y: float
    weight: float | None = None


class Trajectory(VdaModel):
    degree: int
    knot_vector: list[float]
    control_points: list[ControlPoint]


class Corridor(VdaModel):
    """2.1.0 only."""

    left_width: float
    right_width: float
    corridor_ref_point: CorridorRefPoint | None = None
    release_required: bool | None = None  # 3.0: the robot asks fleet control to release the corridor
    release_loss_behavior: str | None = None  # 3.0: STOP or RETURN


class Edge(VdaModel):
    edge_id: str
    sequence_id: UInt
    edge_description: str | None = None
    released: bool
    start_node_id: str
    end_node_id: str
    max_speed: float | None = None
    max_height: float | None = None
    min_height: float | None = None
    orientation: float | None = None
    orientation_type: OrientationType | None = None
    direction: str | None = None
    rotation_allowed: bool | None = None
    max_rotation_speed: float | None = None
    length: float | None = None
    trajectory: Trajectory | None = None
    corridor: Corridor | None = None
    actions: list[Action]


class OrderContent(VdaModel):
    order_id: str
    order_update_id: UInt
    order_description: str | None = None  # 3.0
    zone_set_id: str | None = None
    nodes: list[Node]
    edges: list[Edge]


class Order(MessageHeader, OrderContent):
    pass


# --- instant actions -------------------------------------------------------------------------------


class InstantActionsContent(VdaModel):
    actions: list[Action]


class InstantActions(MessageHeader, InstantActionsContent):
    pass


# --- zone sets and responses (3.0) ------------------------------------------------------------------


class Vertex(VdaModel):
    x: float
    y: float


class Zone(VdaModel):
    """A zone of a zone set; the fields beyond the first four are those of its zone type
    (``vda5050.zones.TYPE_FIELDS``)."""

    zone_id: str
    zone_type: str
    zone_descriptor: str | None = None
    vertices: list[Vertex] = Field(min_length=3)
    release_loss_behavior: str | None = None
    maximum_speed: float | None = None
    # ACTION zones' actions, as on the wire (actionType, blockingType, ...; no actionId)
    entry_actions: list[dict[str, Any]] | None = None
    during_actions: list[dict[str, Any]] | None = None
    exit_actions: list[dict[str, Any]] | None = None
    priority_factor: float | None = None
    penalty_factor: float | None = None
    direction: float | None = None
    directed_limitation: str | None = None
    bidirected_limitation: str | None = None


class ZoneSetDefinition(VdaModel):
    map_id: str
    zone_set_id: str
    zone_set_descriptor: str | None = None
    zones: list[Zone]


class ZoneSetContent(VdaModel):
    zone_set: ZoneSetDefinition


class ZoneSetMessage(MessageHeader, ZoneSetContent):
    pass


class Response(VdaModel):
    """Fleet control's answer to one zone or edge request (``requestId``)."""

    request_id: str
    grant_type: str  # vda5050.zones.GrantType
    lease_expiry: str | None = None  # ISO 8601; none: granted until the robot releases it


class ResponsesContent(VdaModel):
    responses: list[Response]


class Responses(MessageHeader, ResponsesContent):
    pass


# --- state -----------------------------------------------------------------------------------------


class Map(VdaModel):
    """2.1.0 only."""

    map_id: str
    map_version: str
    map_description: str | None = None
    map_status: MapStatus


class NodeState(VdaModel):
    node_id: str
    sequence_id: int
    node_description: str | None = None
    released: bool
    node_position: NodePosition | None = None


class EdgeState(VdaModel):
    edge_id: str
    sequence_id: int
    edge_description: str | None = None
    released: bool
    trajectory: Trajectory | None = None


class AgvPosition(VdaModel):
    x: float
    y: float
    theta: float
    map_id: str
    map_description: str | None = None
    position_initialized: bool
    localization_score: float | None = None
    deviation_range: float | None = None


class Velocity(VdaModel):
    vx: float | None = None
    vy: float | None = None
    omega: float | None = None


class BoundingBoxReference(VdaModel):
    x: float
    y: float
    z: float
    theta: float | None = None


class LoadDimensions(VdaModel):
    length: float
    width: float
    height: float | None = None


class Load(VdaModel):
    load_id: str | None = None
    load_type: str | None = None
    load_position: str | None = None
    bounding_box_reference: BoundingBoxReference | None = None
    load_dimensions: LoadDimensions | None = None
    weight: float | None = None


class ActionState(VdaModel):
    action_id: str
    action_type: str | None = None
    action_description: str | None = None
    action_status: ActionStatus
    result_description: str | None = None


class BatteryState(VdaModel):
    """3.0's ``powerSupply``."""

    battery_charge: float
    battery_voltage: float | None = None
    battery_current: float | None = None  # 3.0
    battery_health: float | None = None
    charging: bool
    reach: float | None = None


class ZoneSetState(VdaModel):
    """3.0: a zone set the robot holds."""

    map_id: str
    zone_set_id: str
    zone_set_status: MapStatus


class Request(VdaModel):
    """3.0: a zone or edge request the robot waits on; fleet control answers on ``responses``."""

    request_id: str
    request_type: str
    request_status: str
    zone_id: str | None = None
    zone_set_id: str | None = None
    edge_id: str | None = None
    sequence_id: int | None = None


class ErrorReference(VdaModel):
    reference_key: str
    reference_value: str


class Error(VdaModel):
    error_type: str
    error_references: list[ErrorReference] | None = None
    error_description: str | None = None
    error_hint: str | None = None
    error_level: ErrorLevel


class InfoReference(VdaModel):
    reference_key: str
    reference_value: str


class Information(VdaModel):
    info_type: str
    info_references: list[InfoReference] | None = None
    info_description: str | None = None
    info_level: InfoLevel


class SafetyState(VdaModel):
    e_stop: EStop
    field_violation: bool


class StateContent(VdaModel):
    maps: list[Map] | None = None
    order_id: str
    order_update_id: UInt
    zone_set_id: str | None = None
    last_node_id: str
    last_node_sequence_id: UInt
    driving: bool
    paused: bool | None = None
    new_base_request: bool | None = None
    distance_since_last_node: float | None = None
    operating_mode: OperatingMode
    node_states: list[NodeState]
    edge_states: list[EdgeState]
    agv_position: AgvPosition | None = None
    velocity: Velocity | None = None
    loads: list[Load] | None = None
    action_states: list[ActionState]
    # 3.0 reports instant actions and zone actions apart from the order's actions (2.x: all in actionStates).
    instant_action_states: list[ActionState] | None = None
    zone_action_states: list[ActionState] | None = None
    zone_sets: list[ZoneSetState] | None = None
    zone_requests: list[Request] | None = None
    edge_requests: list[Request] | None = None
    battery_state: BatteryState
    errors: list[Error]
    information: list[Information] | None = None
    safety_state: SafetyState


class State(MessageHeader, StateContent):
    pass


# --- connection ------------------------------------------------------------------------------------


class ConnectionContent(VdaModel):
    connection_state: ConnectionState


class Connection(MessageHeader, ConnectionContent):
    pass


# --- visualization ---------------------------------------------------------------------------------


class VisualizationContent(VdaModel):
    agv_position: AgvPosition | None = None
    velocity: Velocity | None = None
    reference_state_header_id: UInt | None = None  # 3.0


class Visualization(VisualizationContent):
    """High-rate position feed; neither schema requires any field, the header included."""

    header_id: UInt | None = None
    timestamp: str | None = None
    version: str | None = None
    manufacturer: str | None = None
    serial_number: str | None = None


# --- factsheet -------------------------------------------------------------------------------------


class TypeSpecification(VdaModel):
    series_name: str
    series_description: str | None = None
    agv_kinematic: AgvKinematic | str  # 3.0 allows kinematics beyond the enum
    # Vendors extend the class list (Isaac: MANIPULATOR, HUMANOID); an unknown class is kept as text.
    agv_class: AgvClass | str
    max_load_mass: float
    localization_types: list[LocalizationType | str]  # 3.0: free text
    navigation_types: list[NavigationType | str]
    supported_zones: list[str] | None = None  # 3.0: the zone types the robot knows


class PhysicalParameters(VdaModel):
    speed_min: float
    speed_max: float
    angular_speed_min: float | None = None
    angular_speed_max: float | None = None
    acceleration_max: float
    deceleration_max: float
    height_min: float | None = None  # required by the 2.0.0 schema only
    height_max: float
    width: float
    length: float


class MaxStringLens(VdaModel):
    msg_len: int | None = None
    topic_serial_len: int | None = None
    topic_elem_len: int | None = None
    id_len: int | None = None
    id_numerical_only: bool | None = None
    enum_len: int | None = None
    load_id_len: int | None = None


class MaxArrayLens(VdaModel):
    """Keys on the wire contain literal dots (``order.nodes``), hence explicit aliases."""

    order_nodes: int | None = Field(default=None, alias="order.nodes")
    order_edges: int | None = Field(default=None, alias="order.edges")
    node_actions: int | None = Field(default=None, alias="node.actions")
    edge_actions: int | None = Field(default=None, alias="edge.actions")
    actions_actions_parameters: int | None = Field(default=None, alias="actions.actionsParameters")
    instant_actions: int | None = Field(default=None, alias="instantActions")
    trajectory_knot_vector: int | None = Field(default=None, alias="trajectory.knotVector")
    trajectory_control_points: int | None = Field(default=None, alias="trajectory.controlPoints")
    state_node_states: int | None = Field(default=None, alias="state.nodeStates")
    state_edge_states: int | None = Field(default=None, alias="state.edgeStates")
    state_loads: int | None = Field(default=None, alias="state.loads")
    state_action_states: int | None = Field(default=None, alias="state.actionStates")
    state_errors: int | None = Field(default=None, alias="state.errors")
    state_information: int | None = Field(default=None, alias="state.information")
    error_error_references: int | None = Field(default=None, alias="error.errorReferences")
    information_info_references: int | None = Field(default=None, alias="information.infoReferences")


class Timing(VdaModel):
    min_order_interval: float
    min_state_interval: float
    default_state_interval: float | None = None
    visualization_interval: float | None = None


class ProtocolLimits(VdaModel):
    max_string_lens: MaxStringLens
    max_array_lens: MaxArrayLens
    timing: Timing


class OptionalParameter(VdaModel):
    parameter: str
    support: ParameterSupport
    description: str | None = None


class FactsheetActionParameter(VdaModel):
    key: str
    value_data_type: ValueDataType
    description: str | None = None
    is_optional: bool | None = None


class AgvAction(VdaModel):
    action_type: str
    action_description: str | None = None
    action_scopes: list[ActionScope]
    action_parameters: list[FactsheetActionParameter] | None = None
    result_description: str | None = None
    blocking_types: list[BlockingType] | None = None
    pause_allowed: bool | None = None  # 3.0 (required there)
    cancel_allowed: bool | None = None  # 3.0 (required there)


class ProtocolFeatures(VdaModel):
    optional_parameters: list[OptionalParameter]
    agv_actions: list[AgvAction]


class WheelPosition(VdaModel):
    x: float
    y: float
    theta: float | None = None


class WheelDefinition(VdaModel):
    type: WheelType | str  # 3.0: free text
    is_active_driven: bool
    is_active_steered: bool
    position: WheelPosition
    diameter: float
    width: float
    center_displacement: float | None = None
    constraints: str | None = None


class PolygonPoint(VdaModel):
    x: float
    y: float


class Envelope2d(VdaModel):
    set: str
    polygon_points: list[PolygonPoint]
    description: str | None = None


class Envelope3d(VdaModel):
    set: str
    format: str
    data: dict[str, Any] | None = None
    url: str | None = None
    description: str | None = None


class AgvGeometry(VdaModel):
    wheel_definitions: list[WheelDefinition] | None = None
    envelopes2d: list[Envelope2d] | None = Field(default=None, alias="envelopes2d")  # to_camel says "2D"
    envelopes3d: list[Envelope3d] | None = Field(default=None, alias="envelopes3d")


class LoadSet(VdaModel):
    set_name: str
    load_type: str
    load_positions: list[str] | None = None
    bounding_box_reference: BoundingBoxReference | None = None
    load_dimensions: LoadDimensions | None = None
    max_weight: float | None = None
    min_loadhandling_height: float | None = None
    max_loadhandling_height: float | None = None
    min_loadhandling_depth: float | None = None
    max_loadhandling_depth: float | None = None
    min_loadhandling_tilt: float | None = None
    max_loadhandling_tilt: float | None = None
    agv_speed_limit: float | None = None
    agv_acceleration_limit: float | None = None
    agv_deceleration_limit: float | None = None
    pick_time: float | None = None
    drop_time: float | None = None
    description: str | None = None


class LoadSpecification(VdaModel):
    load_positions: list[str] | None = None
    load_sets: list[LoadSet] | None = None


class VersionInfo(VdaModel):
    """One ``vehicleConfig.versions`` entry (2.1.0)."""

    key: str
    value: str


class Network(VdaModel):
    dns_servers: list[str] | None = None
    ntp_servers: list[str] | None = None
    local_ip_address: str | None = None
    netmask: str | None = None
    default_gateway: str | None = None


class VehicleConfig(VdaModel):
    """2.1.0 only."""

    versions: list[VersionInfo] | None = None
    network: Network | None = None


class FactsheetContent(VdaModel):
    type_specification: TypeSpecification
    physical_parameters: PhysicalParameters
    protocol_limits: ProtocolLimits
    protocol_features: ProtocolFeatures
    agv_geometry: AgvGeometry
    load_specification: LoadSpecification
    localization_parameters: dict[str, Any] | None = None  # 2.0.0 only, an empty object in practice
    vehicle_config: VehicleConfig | None = None


class Factsheet(FactsheetContent):
    """2.1.0's schema does not require ``headerId``/``timestamp``; the rest of the header is required."""

    header_id: UInt | None = None
    timestamp: str | None = None
    version: str
    manufacturer: str
    serial_number: str


Message = Order | InstantActions | State | Connection | Visualization | Factsheet | ZoneSetMessage | Responses
Content = (
    OrderContent
    | InstantActionsContent
    | StateContent
    | ConnectionContent
    | VisualizationContent
    | FactsheetContent
    | ZoneSetContent
    | ResponsesContent
)
