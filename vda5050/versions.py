"""The protocol versions we speak, and the wire translation between them.

Inside, every message has one shape: the ``vda5050.models`` (VDA 5050 2.x names, plus the concepts 3.0
added, such as ``instantActionStates``). On the wire, 2.0.0 and 2.1.0 are that shape; 3.0.0 renamed and
restructured much of it (``agvPosition`` is ``mobileRobotPosition``, ``batteryState`` is ``powerSupply``,
edges lose ``startNodeId``/``endNodeId``, ``allowedDeviationXY`` is an ellipse, enums gained underscores,
...). ``to_wire`` turns a message body in our shape into a version's wire shape, ``from_wire`` a received
body back; the tables below are the whole 2.1.0 -> 3.0.0 difference as far as a message we send or read
carries it (``docs/vda5050-versions.md`` lists all of it, including what we ignore).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from vda5050.errors import ProtocolError
from vda5050.topics import VERSION_PATTERN, Topic

V2_0 = "2.0.0"
V2_1 = "2.1.0"
V3_0 = "3.0.0"
SUPPORTED_VERSIONS = (V2_0, V2_1, V3_0)
MAJOR_3 = 3
INSTANT_ACTION_BLOCKING_3 = "NONE"

Body = dict[str, Any]

# --- renamed keys: path of the key in our (2.x) names -> its 3.0 name ------------------------------------
# A path is dot-separated keys, ``[]`` for "every item of the list". A parent renamed in the table is
# written with its 2.x name here.
_ACTION_3 = {"actionDescription": "actionDescriptor"}
_ACTION_STATE_3 = {"actionDescription": "actionDescriptor", "resultDescription": "actionResult"}
_POSITION_3 = {"agvPosition": "mobileRobotPosition", "agvPosition.positionInitialized": "localized"}


def _under(prefix: str, renames: Mapping[str, str]) -> dict[str, str]:
    return {f"{prefix}.{path}": name for path, name in renames.items()}


RENAMED_IN_3: dict[Topic, dict[str, str]] = {
    Topic.ORDER: {
        "nodes[].nodeDescription": "nodeDescriptor",
        **_under("nodes[].actions[]", _ACTION_3),
        "edges[].edgeDescription": "edgeDescriptor",
        "edges[].maxSpeed": "maximumSpeed",
        "edges[].maxHeight": "maximumMobileRobotHeight",
        "edges[].minHeight": "minimumLoadHandlingDeviceHeight",
        "edges[].rotationAllowed": "reachOrientationBeforeEntering",
        "edges[].corridor.corridorRefPoint": "corridorReferencePoint",
        **_under("edges[].actions[]", _ACTION_3),
    },
    Topic.INSTANT_ACTIONS: _under("actions[]", _ACTION_3),
    Topic.STATE: {
        **_POSITION_3,
        "batteryState": "powerSupply",
        "batteryState.batteryCharge": "stateOfCharge",
        "batteryState.reach": "range",
        "safetyState.eStop": "activeEmergencyStop",
        **_under("actionStates[]", _ACTION_STATE_3),
        **_under("instantActionStates[]", _ACTION_STATE_3),
        **_under("zoneActionStates[]", _ACTION_STATE_3),
        "nodeStates[].nodeDescription": "nodeDescriptor",
        "edgeStates[].edgeDescription": "edgeDescriptor",
        "information[].infoDescription": "infoDescriptor",
        "maps[].mapDescription": "mapDescriptor",
    },
    Topic.VISUALIZATION: _POSITION_3,
    Topic.CONNECTION: {},
    # 3.0-only topics: our names are 3.0's.
    Topic.ZONE_SET: {},
    Topic.RESPONSES: {},
    Topic.FACTSHEET: {
        "typeSpecification.agvKinematic": "mobileRobotKinematics",
        "typeSpecification.agvClass": "mobileRobotClass",
        "typeSpecification.maxLoadMass": "maximumLoadMass",
        "physicalParameters.speedMin": "minimumSpeed",
        "physicalParameters.speedMax": "maximumSpeed",
        "physicalParameters.angularSpeedMin": "minimumAngularSpeed",
        "physicalParameters.angularSpeedMax": "maximumAngularSpeed",
        "physicalParameters.accelerationMax": "maximumAcceleration",
        "physicalParameters.decelerationMax": "maximumDeceleration",
        "physicalParameters.heightMin": "minimumHeight",
        "physicalParameters.heightMax": "maximumHeight",
        "protocolLimits.maxStringLens": "maximumStringLengths",
        "protocolLimits.maxStringLens.msgLen": "maximumMessageLength",
        "protocolLimits.maxStringLens.topicSerialLen": "maximumTopicSerialLength",
        "protocolLimits.maxStringLens.topicElemLen": "maximumTopicElementLength",
        "protocolLimits.maxStringLens.idLen": "maximumIdLength",
        "protocolLimits.maxStringLens.loadIdLen": "maximumLoadIdLength",
        "protocolLimits.maxArrayLens": "maximumArrayLengths",
        "protocolLimits.timing.minOrderInterval": "minimumOrderInterval",
        "protocolLimits.timing.minStateInterval": "minimumStateInterval",
        "protocolFeatures.agvActions": "mobileRobotActions",
        "protocolFeatures.agvActions[].resultDescription": "actionResult",
        "agvGeometry": "mobileRobotGeometry",
        "agvGeometry.envelopes2d[].set": "envelope2dId",
        "agvGeometry.envelopes2d[].polygonPoints": "vertices",
        "agvGeometry.envelopes3d[].set": "envelope3dId",
        "loadSpecification.loadSets[].maxWeight": "maximumWeight",
        "loadSpecification.loadSets[].minLoadhandlingHeight": "minimumLoadhandlingHeight",
        "loadSpecification.loadSets[].maxLoadhandlingHeight": "maximumLoadhandlingHeight",
        "loadSpecification.loadSets[].minLoadhandlingDepth": "minimumLoadhandlingDepth",
        "loadSpecification.loadSets[].maxLoadhandlingDepth": "maximumLoadhandlingDepth",
        "loadSpecification.loadSets[].minLoadhandlingTilt": "minimumLoadhandlingTilt",
        "loadSpecification.loadSets[].maxLoadhandlingTilt": "maximumLoadhandlingTilt",
        "loadSpecification.loadSets[].agvSpeedLimit": "maximumSpeed",
        "loadSpecification.loadSets[].agvAccelerationLimit": "maximumAcceleration",
        "loadSpecification.loadSets[].agvDecelerationLimit": "maximumDeceleration",
        "vehicleConfig": "mobileRobotConfiguration",
    },
}

# --- renamed enum values: path of the value in our names -> {our value: 3.0 value} -----------------------
RENAMED_VALUES_IN_3: dict[Topic, dict[str, dict[str, str]]] = {
    Topic.ORDER: {"edges[].corridor.corridorRefPoint": {"KINEMATICCENTER": "KINEMATIC_CENTER"}},
    Topic.INSTANT_ACTIONS: {},
    Topic.STATE: {"operatingMode": {"TEACHIN": "TEACH_IN"}},
    Topic.VISUALIZATION: {},
    Topic.CONNECTION: {"connectionState": {"CONNECTIONBROKEN": "CONNECTION_BROKEN"}},
    Topic.ZONE_SET: {},
    Topic.RESPONSES: {},
    Topic.FACTSHEET: {
        "typeSpecification.agvKinematic": {
            "DIFF": "DIFFERENTIAL",
            "OMNI": "OMNIDIRECTIONAL",
            "THREEWHEEL": "THREE_WHEEL",
        },
        "typeSpecification.navigationTypes[]": {"AUTONOMOUS": "FREELY_NAVIGATING"},
    },
}

# Keys 3.0 dropped (path in our names): not sent to a 3.0 robot. We never fill them for one anyway.
DROPPED_IN_3: dict[Topic, tuple[str, ...]] = {
    Topic.ORDER: ("zoneSetId", "nodes[].nodePosition.mapDescription"),
    Topic.STATE: ("zoneSetId", "agvPosition.mapDescription"),
    Topic.VISUALIZATION: ("agvPosition.mapDescription",),
    Topic.FACTSHEET: ("protocolLimits.maxStringLens.enumLen", "localizationParameters"),
}


# --- the generic walk ----------------------------------------------------------------------------------


class _Renames:
    """One direction of a topic's tables, keyed by the parent path in the *source* version's names."""

    def __init__(self, keys: Mapping[str, str], values: Mapping[str, Mapping[str, str]], *, up: bool) -> None:
        self.keys: dict[str, dict[str, str]] = {}
        self.values: dict[str, dict[str, str]] = {}
        for path, new_name in keys.items():
            parent, _, old_name = path.rpartition(".")
            if up:
                self.keys.setdefault(parent, {})[old_name] = new_name
            else:
                self.keys.setdefault(_path_in_3(parent, keys), {})[new_name] = old_name
        for path, mapping in values.items():
            source = path if up else _path_in_3(path, keys)
            self.values[source] = dict(mapping) if up else {new: old for old, new in mapping.items()}

    def apply(self, node: Any, path: str = "") -> Any:
        if isinstance(node, dict):
            names = self.keys.get(path, {})
            return {
                names.get(key, key): self.apply(value, f"{path}.{key}" if path else key)
                for key, value in node.items()
            }
        if isinstance(node, list):
            return [self.apply(item, f"{path}[]") for item in node]
        mapping = self.values.get(path)
        if mapping is not None and isinstance(node, str):
            return mapping.get(node, node)
        return node


def _path_in_3(path: str, renames: Mapping[str, str]) -> str:
    """A path in our names -> the same path in 3.0 names (each renamed key replaced)."""
    if not path:
        return path
    ours: list[str] = []
    theirs: list[str] = []
    for segment in path.split("."):
        key = segment.removesuffix("[]")
        brackets = segment[len(key) :]
        name = renames.get(".".join([*ours, key]), key)
        ours.append(segment)
        theirs.append(name + brackets)
    return ".".join(theirs)


_UP = {topic: _Renames(RENAMED_IN_3[topic], RENAMED_VALUES_IN_3[topic], up=True) for topic in RENAMED_IN_3}
_DOWN = {topic: _Renames(RENAMED_IN_3[topic], RENAMED_VALUES_IN_3[topic], up=False) for topic in RENAMED_IN_3}


# --- structural changes 3.0 made --------------------------------------------------------------------------


def _order_to_3(body: Body) -> Body:
    """Edges connect their neighbouring nodes by position (no start/end ids); a deviation radius r is
    the circle a = b = r."""
    for edge in body.get("edges", ()):
        edge.pop("startNodeId", None)
        edge.pop("endNodeId", None)
    for node in body.get("nodes", ()):
        position = node.get("nodePosition") or {}
        radius = position.get("allowedDeviationXY")
        if isinstance(radius, int | float):
            position["allowedDeviationXY"] = {"a": radius, "b": radius, "theta": 0.0}
    return body


def _order_from_3(body: Body) -> Body:
    """Our order shape: each edge names its nodes again; an ellipse's inscribed circle (min(a, b)) is the
    radius, so a node counts as reached only where the ellipse would count it too."""
    nodes = body.get("nodes")
    edges = body.get("edges")
    if isinstance(nodes, list) and isinstance(edges, list):
        for i, edge in enumerate(edges):
            if isinstance(edge, dict) and i + 1 < len(nodes) and all(isinstance(n, dict) for n in nodes):
                edge.setdefault("startNodeId", nodes[i].get("nodeId"))
                edge.setdefault("endNodeId", nodes[i + 1].get("nodeId"))
    for node in nodes if isinstance(nodes, list) else ():
        position = node.get("nodePosition") if isinstance(node, dict) else None
        ellipse = position.get("allowedDeviationXY") if isinstance(position, dict) else None
        if isinstance(ellipse, dict) and {"a", "b"} <= ellipse.keys():
            position["allowedDeviationXY"] = min(ellipse["a"], ellipse["b"])
    return body


def _state_to_3(body: Body) -> Body:
    """3.0 requires ``instantActionStates`` (empty when there are none)."""
    body.setdefault("instantActionStates", [])
    return body


def _instant_actions_to_3(body: Body) -> Body:
    """3.0 instant actions are NONE-blocking, always."""
    for i, action in enumerate(body.get("actions", ())):
        if action.get("blockingType") != INSTANT_ACTION_BLOCKING_3:
            raise ProtocolError(f"actions[{i}].blockingType", "must be NONE in VDA 5050 3.0")
    return body


_TO_3: dict[Topic, Callable[[Body], Body]] = {
    Topic.ORDER: _order_to_3,
    Topic.INSTANT_ACTIONS: _instant_actions_to_3,
    Topic.STATE: _state_to_3,
}
_FROM_3: dict[Topic, Callable[[Body], Body]] = {Topic.ORDER: _order_from_3}


# --- entry points ----------------------------------------------------------------------------------------


def major_of(version: str) -> int:
    return _version_key(version)[0]


def supported_version(version: str) -> str | None:
    """The version we speak to a robot that says it speaks ``version``: the same one, else the newest we
    know of its major version not newer than it (a 3.0.1 robot gets 3.0.0 messages, which it must read);
    None for a major version we do not speak."""
    if version in SUPPORTED_VERSIONS:
        return version
    try:
        wanted = _version_key(version)
    except ProtocolError:
        return None
    candidates = [v for v in SUPPORTED_VERSIONS if major_of(v) == wanted[0] and _version_key(v) <= wanted]
    return max(candidates, key=_version_key) if candidates else None


def _version_key(version: str) -> tuple[int, int, int]:
    match = VERSION_PATTERN.fullmatch(version)
    if match is None:
        raise ProtocolError("version", f"{version!r} is not Major.Minor.Patch")
    return int(match.group(1)), int(match.group(2)), int(match.group(3))


def to_wire(topic: Topic, body: Body, version: str) -> Body:
    """Our message body (wire names of 2.x, no nulls) as ``version`` spells it."""
    if major_of(version) < MAJOR_3:
        return body
    for path in DROPPED_IN_3.get(topic, ()):
        _drop(body, path.split("."))
    body = _UP[topic].apply(body)
    structural = _TO_3.get(topic)
    return structural(body) if structural else body


def from_wire(topic: Topic, body: Body) -> Body:
    """A received body in our names, read by the version it names in its header (a body without a usable
    ``version`` is taken as 2.x, the shape our models read anyway)."""
    version = body.get("version")
    try:
        is_3 = isinstance(version, str) and major_of(version) >= MAJOR_3
    except ProtocolError:
        is_3 = False
    if not is_3:
        return body
    structural = _FROM_3.get(topic)
    body = _DOWN[topic].apply(body)
    return structural(body) if structural else body


def _drop(node: Any, keys: list[str]) -> None:
    if isinstance(node, list):
        for item in node:
            _drop(item, keys)
        return
    if not isinstance(node, dict):
        return
    head, *rest = keys
    if not rest:
        node.pop(head, None)
        return
    name = head.removesuffix("[]")
    if name in node:
        _drop(node[name], rest)
