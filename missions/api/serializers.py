"""Mission API bodies: the mission a client submits, its tree's nodes, route updates, and the mission
object every endpoint returns. The node serializers' docstrings are also the GET /behaviors descriptions."""

from datetime import datetime
from typing import Any
from urllib.parse import urlsplit

from django.conf import settings
from drf_spectacular.utils import extend_schema_field
from rest_framework import serializers

from dispatch.vocabulary import DEFAULT_NOTIFY_TIMEOUT, NodeKind
from kit.api.fields import (
    MAX_SECONDS,
    JsonBooleanField,
    JsonIntegerField,
    JsonStringField,
    NumberField,
    ObjectNameField,
    validate_free_json,
    validate_int64,
    validate_positive,
)
from kit.api.serializers import ObjectNameSerializer, Pose2DSerializer, SpecSerializer, StrictSerializer
from missions.choices import FailureCategory, Lifecycle, MissionPurpose, MissionState
from missions.filters import MOST_RECENT_MAX
from missions.models import Mission
from missions.services import PRIORITY_MAX, PRIORITY_MIN
from missions.tuning import MAX_NOTIFY_TIMEOUT

NOTIFY_URL_SCHEMES = frozenset({"http", "https"})
FREE_JSON_HELP = f"At most {settings.API_MAX_PARAMETERS_BYTES} bytes as JSON."


# --- mission tree nodes ---------------------------------------------------------------------------------


class RouteNodeSerializer(StrictSerializer):
    """Drive through a list of waypoints (one VDA 5050 order); the last one must be reached."""

    waypoints = Pose2DSerializer(
        many=True,
        allow_empty=False,
        max_length=settings.API_MAX_WAYPOINTS,
        help_text=f"At least one Pose2D, at most {settings.API_MAX_WAYPOINTS}.",
    )


class MoveNodeSerializer(StrictSerializer):
    """Move relative to the current pose: drive `distance` metres straight ahead, or turn by `rotation`
    radians. Exactly one of the two is set."""

    distance = NumberField(required=False, allow_null=True, default=None, help_text="Metres straight ahead.")
    rotation = NumberField(required=False, allow_null=True, default=None, help_text="Radians to turn.")

    def validate(self, attrs: dict) -> dict:
        given = [field for field in ("distance", "rotation") if attrs.get(field) is not None]
        if len(given) != 1:
            raise serializers.ValidationError(
                f"Exactly one of distance or rotation must be set, but {len(given)} are set.",
                code="move_exactly_one",
            )
        return attrs


class ActionNodeSerializer(StrictSerializer):
    """Run an action on the robot (a VDA 5050 order whose only node carries the action)."""

    action_type = JsonStringField(help_text="The robot's name for the action, e.g. dummy_action.")
    action_parameters = serializers.DictField(
        default=dict,
        validators=[validate_free_json, validate_int64],
        help_text=(
            f"Parameters of the action; values keep their JSON types. {FREE_JSON_HELP} Integers fit in "
            "64 bits."
        ),
    )


class NotifyNodeSerializer(StrictSerializer):
    """Make an HTTP POST of `json_data` to `url`; the node succeeds if the call does."""

    url = JsonStringField(help_text="http:// or https:// URL to POST to.")
    json_data = serializers.DictField(
        default=dict, validators=[validate_free_json], help_text=f"JSON body of the POST. {FREE_JSON_HELP}"
    )
    timeout = JsonIntegerField(
        default=DEFAULT_NOTIFY_TIMEOUT,
        min_value=1,
        max_value=MAX_NOTIFY_TIMEOUT,
        help_text="Seconds to wait for the response.",
    )

    def validate_url(self, url: str) -> str:
        parts = urlsplit(url)
        if parts.scheme not in NOTIFY_URL_SCHEMES or not parts.netloc:
            raise serializers.ValidationError(
                "Must be an absolute http:// or https:// URL.", code="invalid_url"
            )
        return url


class ConstantNodeSerializer(StrictSerializer):
    """Succeed (or fail, with success false) at once; useful in selectors and for tests."""

    success = JsonBooleanField(default=True)


# Composite nodes have no parameters: their body is an empty object.
EMPTY_OBJECT_SCHEMA = {"type": "object", "additionalProperties": False, "example": {}}


@extend_schema_field(EMPTY_OBJECT_SCHEMA)
class SequenceNodeSerializer(StrictSerializer):
    """Run the children in order: fail as soon as one fails, succeed when all have succeeded."""


@extend_schema_field(EMPTY_OBJECT_SCHEMA)
class SelectorNodeSerializer(StrictSerializer):
    """Run the children in order: succeed as soon as one succeeds, fail when all have failed."""


# The node kinds in the order GET /behaviors lists them, each with the serializer of its body.
NODE_KIND_SERIALIZERS: dict[str, type[serializers.Serializer]] = {
    NodeKind.ROUTE: RouteNodeSerializer,
    NodeKind.MOVE: MoveNodeSerializer,
    NodeKind.ACTION: ActionNodeSerializer,
    NodeKind.NOTIFY: NotifyNodeSerializer,
    NodeKind.CONSTANT: ConstantNodeSerializer,
    NodeKind.SEQUENCE: SequenceNodeSerializer,
    NodeKind.SELECTOR: SelectorNodeSerializer,
}


def node_description(kind: str) -> str:
    """What a node of this kind does, in one line (its serializer's docstring)."""
    return " ".join(NODE_KIND_SERIALIZERS[kind].__doc__.split())


class MissionNodeSerializer(StrictSerializer):
    """One node of a mission tree: a name, a parent, and exactly one kind."""

    name = ObjectNameField(
        required=False,
        allow_null=True,
        default=None,
        help_text='Unique in the tree; "root" is reserved. Default: its index in mission_tree ("0", "1").',
    )
    parent = ObjectNameField(
        default="root",
        help_text='A selector or sequence that appears earlier in mission_tree, or "root".',
    )
    selector = SelectorNodeSerializer(
        required=False, allow_null=True, help_text=node_description(NodeKind.SELECTOR)
    )
    sequence = SequenceNodeSerializer(
        required=False, allow_null=True, help_text=node_description(NodeKind.SEQUENCE)
    )
    route = RouteNodeSerializer(required=False, allow_null=True, help_text=node_description(NodeKind.ROUTE))
    move = MoveNodeSerializer(required=False, allow_null=True, help_text=node_description(NodeKind.MOVE))
    action = ActionNodeSerializer(
        required=False, allow_null=True, help_text=node_description(NodeKind.ACTION)
    )
    notify = NotifyNodeSerializer(
        required=False, allow_null=True, help_text=node_description(NodeKind.NOTIFY)
    )
    constant = ConstantNodeSerializer(
        required=False, allow_null=True, help_text=node_description(NodeKind.CONSTANT)
    )


class RouteUpdatesField(serializers.DictField):
    """POST /mission/{name}/update body and spec.update_nodes: new waypoints per route node name (at most
    as many as a tree has nodes)."""

    child = RouteNodeSerializer()

    def to_internal_value(self, data: Any) -> dict:
        if isinstance(data, dict) and len(data) > settings.API_MAX_TREE_NODES:
            raise serializers.ValidationError(
                f"Ensure this field has no more than {settings.API_MAX_TREE_NODES} elements.",
                code="max_length",
            )
        return super().to_internal_value(data)


def schema_constraints(result: dict, generator: Any, request: Any, public: bool) -> dict:
    """drf-spectacular hook: what the mission serializers and filters enforce but cannot state themselves.

    A node has exactly one kind: oneOf over the kinds says it, as the branch of a kind matches when that
    kind is present and not null, so exactly one branch matches when exactly one kind is given (the others
    absent or null). Nested lists (the tree, a route's waypoints) and route updates get their bounds, and
    most_recent its range.
    """
    schemas = result["components"]["schemas"]
    schemas["MissionNodeRequest"]["oneOf"] = [
        {"required": [kind], "properties": {kind: {"type": "object"}}} for kind in NODE_KINDS
    ]
    mission = schemas["MissionCreateRequest"]["properties"]
    mission["mission_tree"].update(minItems=1, maxItems=settings.API_MAX_TREE_NODES)
    mission["update_nodes"]["maxProperties"] = settings.API_MAX_TREE_NODES
    update = result["paths"]["/mission/{name}/update"]["post"]["requestBody"]["content"]["application/json"]
    update["schema"]["maxProperties"] = settings.API_MAX_TREE_NODES
    waypoints = schemas["RouteNodeRequest"]["properties"]["waypoints"]
    waypoints.update(minItems=1, maxItems=settings.API_MAX_WAYPOINTS)
    for parameter in result["paths"]["/mission"]["get"]["parameters"]:
        if parameter["name"] == "most_recent":
            parameter["schema"].update(minimum=0, maximum=MOST_RECENT_MAX)
    return result


# --- the mission -------------------------------------------------------------------------------------------


def _names_field(help_text: str) -> serializers.ListField:
    return serializers.ListField(
        child=JsonStringField(),
        default=list,
        max_length=settings.API_MAX_LABELS,
        help_text=f"{help_text} At most {settings.API_MAX_LABELS}.",
    )


class RobotSelectorSerializer(StrictSerializer):
    """Which robots may run an unbound mission; an omitted or empty field asks nothing. A selector no robot
    meets yet is accepted: the mission waits, its waiting_reason says for what."""

    labels = _names_field("The robot carries every one of these labels.")
    robot_types = _names_field("The robot's type (its factsheet's agv_class) is one of these.")
    action_types = _names_field("The robot's factsheet lists every one of these action types.")


class MissionSpecSerializer(SpecSerializer):
    robot = ObjectNameField(
        required=False,
        allow_null=True,
        default=None,
        help_text=(
            "Name of the robot to run the mission; it need not exist yet. Omitted or null: the mission is "
            "unbound, and the dispatcher binds it to a free capable robot (see robot_selector), whose name "
            "it then holds; until then status.waiting_reason says why it waits."
        ),
    )
    priority = JsonIntegerField(
        default=0,
        min_value=PRIORITY_MIN,
        max_value=PRIORITY_MAX,
        help_text=(
            "Higher first: a robot's next mission is the highest-priority one of its queue (oldest first "
            "among equals), and assignment serves higher priorities first. A running mission is never "
            "preempted."
        ),
    )
    robot_selector = RobotSelectorSerializer(
        required=False,
        allow_null=True,
        default=None,
        help_text="Only on a mission without robot: which robots may run it. Null: any robot.",
    )
    mission_tree = MissionNodeSerializer(
        many=True,
        allow_empty=False,
        max_length=settings.API_MAX_TREE_NODES,
        help_text=(
            "The nodes of the tree under the implicit root sequence; each parent before its children; at "
            f"most {settings.API_MAX_TREE_NODES}."
        ),
    )
    timeout = NumberField(
        default=Mission._meta.get_field("timeout").get_default(),
        max_value=MAX_SECONDS,
        validators=[validate_positive],
        help_text="Seconds the mission may run before it fails.",
    )
    deadline = serializers.DateTimeField(
        allow_null=True,
        default=None,
        help_text="A mission still queued at its deadline never starts, one still running fails (DEADLINE).",
    )
    needs_canceled = JsonBooleanField(default=False, help_text="Set by POST /mission/{name}/cancel.")
    update_nodes = RouteUpdatesField(
        allow_null=True,
        default=None,
        help_text="New waypoints per route node, set by POST /mission/{name}/update.",
    )

    def validate(self, attrs: dict) -> dict:
        if attrs.get("robot") is not None and attrs.get("robot_selector") is not None:
            raise serializers.ValidationError(
                {"robot_selector": ["Only a mission without robot has a robot_selector."]},
                code="selector_with_robot",
            )
        return attrs


class MissionCreateSerializer(ObjectNameSerializer, MissionSpecSerializer):
    """A mission's spec plus the name (or name prefix) of the new mission."""


class NodeStatusSerializer(serializers.Serializer):
    state = serializers.ChoiceField(choices=MissionState.choices)
    error_msg = serializers.CharField(allow_null=True)


class BindingSerializer(serializers.Serializer):
    robot = serializers.CharField()
    bound_at = serializers.DateTimeField()
    released_at = serializers.DateTimeField(allow_null=True)
    reason = serializers.CharField(allow_null=True, help_text="Why the binding was released.")


class MissionStatusSerializer(serializers.Serializer):
    """The mission's progress, written by the dispatch engine."""

    state = serializers.ChoiceField(choices=MissionState.choices)
    current_node = serializers.IntegerField(help_text="Index in mission_tree of the current node.")
    node_status = serializers.DictField(
        child=NodeStatusSerializer(), help_text='Per node name, "root" included.'
    )
    task_status = serializers.DictField(child=serializers.IntegerField())
    start_timestamp = serializers.DateTimeField(allow_null=True)
    end_timestamp = serializers.DateTimeField(allow_null=True)
    failure_reason = serializers.CharField(allow_null=True)
    failure_category = serializers.ChoiceField(choices=FailureCategory.choices, allow_null=True)
    waiting_reason = serializers.CharField(
        allow_null=True,
        help_text="Why a queued mission has not started yet (e.g. the robot is offline, a map it names is "
        "not enabled; for an unbound mission: no robot carries its labels, every capable robot is busy, "
        "...), or why a running mission's next route leaf waits for its map.",
    )
    assignment = BindingSerializer(
        many=True,
        help_text="The robots assignment bound the mission to, oldest first (empty for a mission posted "
        "with its robot). A binding released (its robot went offline, errored, ran low or was deleted "
        "before taking the mission's first order) has released_at and reason; the mission is then "
        "unbound again.",
    )


class MissionSerializer(MissionSpecSerializer):
    """A mission: its spec fields (the tree normalized), name, status and lifecycle."""

    name = serializers.CharField()
    purpose = serializers.ChoiceField(
        choices=MissionPurpose.choices,
        allow_null=True,
        help_text="A trip the dispatch core made itself (README \"Stations: charging and parking\"): CHARGE "
        "(a route to a charger, then startCharging) or PARK (a route to a parking station); null for a "
        "client's mission.",
    )
    status = MissionStatusSerializer(source="*")
    lifecycle = serializers.ChoiceField(choices=Lifecycle.choices)

    def to_representation(self, instance: Mission) -> dict[str, Any]:
        """The declared fields' output, built directly: the stored tree is the one this API validated
        (defaults applied), and the generic nested serializers cost more than the rest of a request.
        Tests check that both agree."""
        return {
            "robot": instance.robot,
            "mission_tree": [
                {
                    "name": node["name"],
                    "parent": node["parent"],
                    **{kind: node.get(kind) for kind in NODE_KINDS},
                }
                for node in instance.mission_tree
            ],
            "timeout": instance.timeout,
            "deadline": _datetime(instance.deadline),
            "needs_canceled": instance.needs_canceled,
            "update_nodes": instance.update_nodes,
            "priority": instance.priority,
            "robot_selector": instance.robot_selector,
            "name": instance.name,
            "purpose": instance.purpose,
            "status": {
                "state": instance.state,
                "current_node": instance.current_node,
                "node_status": instance.node_status,
                "task_status": instance.task_status,
                "start_timestamp": _datetime(instance.start_timestamp),
                "end_timestamp": _datetime(instance.end_timestamp),
                "failure_reason": instance.failure_reason,
                "failure_category": instance.failure_category,
                "waiting_reason": instance.waiting_reason,
                "assignment": instance.assignment,
            },
            "lifecycle": instance.lifecycle,
        }


NODE_KINDS = tuple(name for name in MissionNodeSerializer._declared_fields if name not in ("name", "parent"))
_DATETIME = serializers.DateTimeField()


def _datetime(value: datetime | None) -> str | None:
    return None if value is None else _DATETIME.to_representation(value)
