"""Operator view of missions: read-only (missions are created through the API), with cancel and delete
going through the same services as the API."""

import json
from collections.abc import Iterable
from dataclasses import dataclass

from django.contrib import admin
from django.contrib.auth import get_permission_codename
from django.db.models import QuerySet
from django.http import HttpRequest
from django.template.loader import render_to_string
from django.urls import reverse
from django.utils.html import format_html
from django.utils.safestring import SafeString

from access.authentication import request_actor
from dispatch.engine import Node, TreeError, apply_route_updates, parse_tree
from dispatch.vocabulary import MissionState, NodeKind
from kit.admin import ServiceAdmin, call_service_for_each, delete_through_service
from missions.models import Mission
from missions.services import mission_cancel, mission_delete, mission_prioritize
from robots.models import Robot

TREE_INDENT_PX = 20
UNBOUND = "(unbound)"
PRIORITY_STEP = 10  # what the admin's raise and lower actions add or take
# Longest rendering of an action's parameters in the tree view before it is cut.
ACTION_PARAMETERS_MAX_CHARS = 80
STATE_COLOURS = {
    MissionState.PENDING: "#6c757d",
    MissionState.RUNNING: "#0d6efd",
    MissionState.COMPLETED: "#198754",
    MissionState.CANCELED: "#fd7e14",
    MissionState.FAILED: "#dc3545",
}


def state_badge(state: str) -> SafeString:
    """A mission or node state as a coloured label."""
    return format_html(
        '<span style="background:{};color:#fff;padding:1px 6px;border-radius:8px;font-size:11px">{}</span>',
        STATE_COLOURS.get(state, "#6c757d"),
        state,
    )


@dataclass(frozen=True)
class TreeRow:
    """One node of a mission tree as a line of the indented tree view."""

    name: str
    kind: str
    params: str
    badge: SafeString
    error_msg: str
    depth: int
    is_current: bool

    @property
    def indent_px(self) -> int:
        return self.depth * TREE_INDENT_PX


def node_params(node: Node, updated: bool) -> str:
    """The parameters an operator needs to recognise a node, in one short line."""
    params = node.params
    if node.kind == NodeKind.ROUTE:
        return f"{len(params.get('waypoints', []))} waypoint(s)" + (" (updated)" if updated else "")
    if node.kind == NodeKind.MOVE:
        if params.get("distance") is not None:
            return f"distance {params['distance']} m"
        return f"rotation {params.get('rotation')} rad"
    if node.kind == NodeKind.ACTION:
        parameters = params.get("action_parameters") or {}
        text = f"action_type {params.get('action_type')}" + (
            f", parameters {json.dumps(parameters)}" if parameters else ""
        )
        return text[:ACTION_PARAMETERS_MAX_CHARS]
    if node.kind == NodeKind.NOTIFY:
        return f"url {params.get('url')}"
    if node.kind == NodeKind.CONSTANT:
        return "success" if params.get("success", True) else "failure"
    return ""


def mission_tree_rows(mission: Mission) -> list[TreeRow]:
    """The mission tree depth-first from the implicit root, each node with its stored status; routes show
    their updated waypoints. Raises TreeError for a stored tree the engine cannot parse."""
    update_nodes = mission.update_nodes or {}
    tree = apply_route_updates(parse_tree(mission.mission_tree), update_nodes)
    running = mission.state == MissionState.RUNNING
    rows: list[TreeRow] = []

    def visit(node: Node, depth: int) -> None:
        status = mission.node_status.get(node.name) or {}
        rows.append(
            TreeRow(
                name=node.name,
                kind=node.kind,
                params=node_params(node, updated=node.name in update_nodes),
                badge=state_badge(status.get("state", MissionState.PENDING)),
                error_msg=status.get("error_msg") or "",
                depth=depth,
                is_current=running and node.index == mission.current_node,
            )
        )
        for child in node.children:
            visit(tree.node(child), depth + 1)

    visit(tree.root, 0)
    return rows


@admin.register(Mission)
class MissionAdmin(ServiceAdmin):
    list_display = (
        "name",
        "robot_or_unbound",
        "priority",
        "state_label",
        "waiting_reason",
        "current_node_name",
        "start_timestamp",
        "end_timestamp",
        "failure_reason",
        "failure_category",
        "lifecycle",
    )
    list_filter = ("state", ("robot", admin.EmptyFieldListFilter), "failure_category", "lifecycle")
    search_fields = ("name", "robot")
    date_hierarchy = "start_timestamp"
    ordering = ("-queue_position",)
    list_per_page = 50
    actions = ("cancel_missions", "raise_priority", "lower_priority")
    fieldsets = (
        (None, {"fields": ("name", "robot_link", "state_label", "lifecycle", "needs_canceled")}),
        ("Assignment", {"fields": ("priority", "robot_selector", "assignment")}),
        (
            "Progress",
            {
                "fields": (
                    "current_node_name",
                    "waiting_reason",
                    "start_timestamp",
                    "end_timestamp",
                    "timeout",
                    "deadline",
                )
            },
        ),
        ("Failure", {"fields": ("failure_reason", "failure_category")}),
        ("Mission tree", {"fields": ("tree_view",)}),
        (
            "Current VDA 5050 order",
            {"classes": ("collapse",), "fields": ("order", "order_sent_at", "order_accepted", "attempts")},
        ),
        ("Progress on the order", {"classes": ("collapse",), "fields": ("progress", "progress_seen_at")}),
        (
            "Raw",
            {
                "classes": ("collapse",),
                "fields": (
                    "mission_tree",
                    "update_nodes",
                    "node_status",
                    "task_status",
                    "created_at",
                    "updated_at",
                ),
            },
        ),
    )

    # Missions come from the API and change only through the engine: the change page is a view page.
    def has_add_permission(self, request: HttpRequest) -> bool:
        return False

    def has_change_permission(self, request: HttpRequest, obj: Mission | None = None) -> bool:
        return False

    def has_cancel_permission(self, request: HttpRequest) -> bool:
        """Cancelling is an operator's change to a mission, so it needs the model's change permission."""
        return request.user.has_perm(f"{self.opts.app_label}.{get_permission_codename('change', self.opts)}")

    @admin.display(description="state", ordering="state")
    def state_label(self, mission: Mission) -> SafeString:
        return state_badge(mission.state)

    @admin.display(description="current node")
    def current_node_name(self, mission: Mission) -> str:
        if 0 <= mission.current_node < len(mission.mission_tree):
            return mission.mission_tree[mission.current_node].get("name", str(mission.current_node))
        return "-"

    @admin.display(description="robot", ordering="robot")
    def robot_or_unbound(self, mission: Mission) -> str:
        return UNBOUND if mission.robot is None else mission.robot

    @admin.display(description="robot")
    def robot_link(self, mission: Mission) -> str:
        if mission.robot is None:
            return UNBOUND
        if not Robot.objects.filter(name=mission.robot).exists():
            return mission.robot
        return format_html(
            '<a href="{}">{}</a>', reverse("admin:robots_robot_change", args=[mission.robot]), mission.robot
        )

    @admin.display(description="nodes")
    def tree_view(self, mission: Mission) -> str:
        try:
            rows = mission_tree_rows(mission)
        except TreeError as error:
            return f"The stored mission tree is invalid: {error}"
        return render_to_string("admin/missions/mission/mission_tree.html", {"rows": rows})

    @admin.action(description="Cancel selected missions", permissions=["cancel"])
    def cancel_missions(self, request: HttpRequest, queryset: QuerySet[Mission]) -> None:
        actor = request_actor(request)
        call_service_for_each(
            self,
            request,
            queryset,
            lambda mission: mission_cancel(actor=actor, mission=mission),
            "Cancel requested",
        )

    @admin.action(description=f"Raise priority by {PRIORITY_STEP}", permissions=["cancel"])
    def raise_priority(self, request: HttpRequest, queryset: QuerySet[Mission]) -> None:
        self._shift_priority(request, queryset, PRIORITY_STEP)

    @admin.action(description=f"Lower priority by {PRIORITY_STEP}", permissions=["cancel"])
    def lower_priority(self, request: HttpRequest, queryset: QuerySet[Mission]) -> None:
        self._shift_priority(request, queryset, -PRIORITY_STEP)

    def _shift_priority(self, request: HttpRequest, queryset: QuerySet[Mission], by: int) -> None:
        actor = request_actor(request)
        call_service_for_each(
            self,
            request,
            queryset,
            lambda mission: mission_prioritize(actor=actor, mission=mission, priority=mission.priority + by),
            "Priority changed",
        )

    def delete_queryset(self, request: HttpRequest, queryset: Iterable[Mission]) -> None:
        delete_through_service(
            self,
            request,
            queryset,
            lambda mission: mission_delete(actor=request_actor(request), mission=mission),
            "their robot has confirmed the cancel",
        )
