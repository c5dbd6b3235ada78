"""Operator view of robots: the spec is editable, the status is what the robot reports; creating, deleting
and teleop go through the same services as the API."""

from collections.abc import Iterable, Mapping
from typing import Any

from django import forms
from django.contrib import admin
from django.contrib.admin.utils import flatten_fieldsets
from django.db.models import QuerySet
from django.forms.models import model_to_dict
from django.http import HttpRequest
from django.utils.safestring import SafeString

from access.authentication import request_actor
from kit.admin import (
    ServiceAdmin,
    SpecAdminForm,
    call_service_for_each,
    delete_through_service,
    html_table,
    pose_text,
    serializer_errors,
    spec_validated,
)
from robots.api.serializers import MapActionRequestSerializer, RobotSpecSerializer, RobotVda5050Serializer
from robots.choices import MapAction, SettingSource, TeleopAction
from robots.models import Robot, RobotMapAction
from robots.selectors import robot_map_actions
from robots.services import (
    robot_charge,
    robot_create,
    robot_delete,
    robot_map_action,
    robot_teleop,
    robot_update_spec,
)

BATTERY_FIELDS = ("battery_critical_level", "battery_recommended_minimum", "battery_recommended_maximum")
# Spec fields an operator may edit on an existing robot; teleop is switched with the actions instead,
# so that the service checks the robot's state and tells the robot.
EDITABLE_SPEC_FIELDS = ("labels", *BATTERY_FIELDS, "heartbeat_timeout")
STATUS_FIELDS = (
    "state",
    "state_since",
    "operating_mode",
    "online",
    "battery_level",
    "charge_requested",
    "charging_waiting_reason",
    "zones",
    "pose",
    "position_initialized",
    "last_state_at",
    "agv_class",
    "speed_max",
    "hardware_version",
    "software_version",
    "info_messages",
    "errors",
)
IDENTITY_FIELDS = (
    "interface_name",
    "manufacturer",
    "serial_number",
    ("protocol_version", "protocol_version_source"),
    ("instant_actions_key", "instant_actions_key_source"),
    "compatibility_rules",
)
SPEC_FIELDS = (*EDITABLE_SPEC_FIELDS, "switch_teleop")


def robot_spec(values: Mapping[str, Any]) -> dict[str, Any]:
    """Spec fields (by model field name) in the API's spec shape, as the robot services take them."""
    return {
        "labels": values["labels"],
        "battery": {field.removeprefix("battery_"): values[field] for field in BATTERY_FIELDS},
        "heartbeat_timeout": values["heartbeat_timeout"],
        "switch_teleop": values["switch_teleop"],
    }


def vda5050_spec(robot: Robot) -> dict[str, Any]:
    """The robot's VDA 5050 spec as the API takes it: its identity and the protocol settings an operator
    chose (a learned or default one stays what it is, see `robots.services`)."""
    shown = RobotVda5050Serializer(robot).data
    spec = {key: shown[key] for key in ("interface_name", "manufacturer", "serial_number")}
    if robot.protocol_version_source == SettingSource.OPERATOR:
        spec["version"] = robot.protocol_version
    if robot.instant_actions_key_source == SettingSource.OPERATOR:
        spec["instant_actions_key"] = robot.instant_actions_key
    return spec


class RobotAdminForm(SpecAdminForm):
    """The spec part of a robot, checked by the API's own spec serializer so that the admin accepts exactly
    what the API accepts; `spec` then holds it in the services' shape."""

    class Meta:
        model = Robot
        # The admin narrows this to the fields of the add or change page.
        fields = ("name", *SPEC_FIELDS)

    def clean(self) -> dict[str, Any]:
        cleaned_data = super().clean()
        if self.errors:
            return cleaned_data
        spec = robot_spec({**model_to_dict(self.instance, fields=SPEC_FIELDS), **cleaned_data})
        if not self.instance._state.adding:
            spec["vda5050"] = vda5050_spec(self.instance)
        self.spec = spec_validated(self, RobotSpecSerializer, spec)
        return cleaned_data


@admin.register(Robot)
class RobotAdmin(ServiceAdmin):
    form = RobotAdminForm
    list_display = (
        "name",
        "state",
        "online",
        "battery_level",
        "pose",
        "agv_class",
        "protocol_version",
        "lifecycle",
        "last_state_at",
        "updated_at",
    )
    list_filter = ("state", "online", "lifecycle", "agv_class", "protocol_version")
    search_fields = ("name",)
    ordering = ("name",)
    list_per_page = 50
    actions = ("start_teleop", "stop_teleop", "charge")
    add_fieldsets = (
        (None, {"fields": ("name",)}),
        ("Spec", {"fields": ("labels", BATTERY_FIELDS, "heartbeat_timeout", "switch_teleop")}),
    )
    fieldsets = (
        (None, {"fields": ("name", "lifecycle")}),
        ("Spec", {"fields": ("labels", BATTERY_FIELDS, "heartbeat_timeout", "switch_teleop")}),
        ("Status", {"fields": STATUS_FIELDS}),
        ("VDA 5050 identity", {"fields": IDENTITY_FIELDS}),
        ("Maps", {"fields": ("maps_reported", "map_actions")}),
        ("Factsheet", {"classes": ("collapse",), "fields": ("factsheet",)}),
        ("Timestamps", {"fields": ("created_at", "updated_at")}),
    )

    def get_fieldsets(self, request: HttpRequest, obj: Robot | None = None) -> tuple:
        return self.add_fieldsets if obj is None else self.fieldsets

    def get_readonly_fields(self, request: HttpRequest, obj: Robot | None = None) -> tuple[str, ...]:
        if obj is None:
            return ()
        return tuple(
            field for field in flatten_fieldsets(self.fieldsets) if field not in EDITABLE_SPEC_FIELDS
        )

    @admin.display(description="pose")
    def pose(self, robot: Robot) -> str:
        return pose_text(robot)

    @admin.display(description="zones")
    def zones(self, robot: Robot) -> str:
        """The RELEASE zones it holds and waits for (the zone plan's; Zone sets admin: its grants)."""
        held, waiting = (
            ", ".join(f"{zone['map_id']}/{zone['zone_id']}" for zone in robot.zone_access.get(key, ()))
            for key in ("held", "waiting")
        )
        return f"holds {held or 'none'}; waits for {waiting or 'none'}"

    @admin.display(description="maps")
    def maps_reported(self, robot: Robot) -> SafeString | str:
        """What the robot reports (VDA 5050 2.1+ state.maps)."""
        if not robot.maps:
            return "none reported"
        return html_table(
            ("map_id", "map_version", "map_status", "map_description"),
            (
                (m["map_id"], m["map_version"], m["map_status"], m["map_description"] or "")
                for m in robot.maps
            ),
        )

    @admin.display(description="map actions")
    def map_actions(self, robot: Robot) -> SafeString | str:
        """downloadMap, enableMap and deleteMap asked through the API, newest first, as the robot reported
        them."""
        actions = list(robot_map_actions(robot=robot))
        if not actions:
            return "none"
        return html_table(
            ("asked", "action", "parameters", "status"),
            (
                (
                    a.created_at,
                    a.action_type,
                    ", ".join(f"{k}={v}" for k, v in (a.parameters or {}).items()),
                    a.status or "not reported yet",
                )
                for a in actions
            ),
        )

    def save_model(self, request: HttpRequest, obj: Robot, form: RobotAdminForm, change: bool) -> None:
        if not change:
            robot_create(actor=request_actor(request), name=obj.name, prefix=None, spec=form.spec)
        elif form.changed_data:
            robot_update_spec(actor=request_actor(request), robot=obj, spec=form.spec)

    def delete_queryset(self, request: HttpRequest, queryset: Iterable[Robot]) -> None:
        delete_through_service(
            self,
            request,
            queryset,
            lambda robot: robot_delete(actor=request_actor(request), robot=robot),
            "the engine has failed their running mission",
        )

    def teleop(self, request: HttpRequest, queryset: QuerySet[Robot], action: TeleopAction) -> None:
        call_service_for_each(
            self,
            request,
            queryset,
            lambda robot: robot_teleop(actor=request_actor(request), robot=robot, action=action),
            f"{action} teleop requested",
        )

    @admin.action(description="Start teleop", permissions=["change"])
    def start_teleop(self, request: HttpRequest, queryset: QuerySet[Robot]) -> None:
        self.teleop(request, queryset, TeleopAction.START)

    @admin.action(description="Stop teleop", permissions=["change"])
    def stop_teleop(self, request: HttpRequest, queryset: QuerySet[Robot]) -> None:
        self.teleop(request, queryset, TeleopAction.STOP)

    @admin.action(description="Charge now", permissions=["change"])
    def charge(self, request: HttpRequest, queryset: QuerySet[Robot]) -> None:
        call_service_for_each(
            self,
            request,
            queryset,
            lambda robot: robot_charge(actor=request_actor(request), robot=robot),
            "sent to charge",
        )


class MapActionAdminForm(forms.ModelForm):
    """A map action for a robot, checked by the API's own request serializer (the admin accepts exactly
    what POST /robot/{name}/map accepts); `request_body` then holds it."""

    action = forms.ChoiceField(choices=MapAction.choices)
    map_id = forms.CharField(strip=False)
    map_version = forms.CharField(strip=False)
    map_download_link = forms.CharField(strip=False, required=False, help_text="downloadMap only, required.")
    map_hash = forms.CharField(strip=False, required=False, help_text="downloadMap only, optional.")

    class Meta:
        model = RobotMapAction
        fields = ("robot",)

    def clean(self) -> dict[str, Any]:
        cleaned_data = super().clean()
        if self.errors:
            return cleaned_data
        body = {
            key: cleaned_data[key]
            for key in MapActionRequestSerializer._declared_fields
            if cleaned_data.get(key) not in (None, "")
        }
        serializer = MapActionRequestSerializer(data=body)
        if serializer.is_valid():
            self.request_body = serializer.validated_data
        for path, message in serializer_errors(serializer.errors):
            field = path[0] if path and path[0] in self.fields else None
            self.add_error(field, message)
        return cleaned_data


@admin.register(RobotMapAction)
class RobotMapActionAdmin(ServiceAdmin):
    """Map actions asked of robots, with the status each robot reported; an operator adds one to have a
    robot download, enable or delete a map (through the same service as the API)."""

    form = MapActionAdminForm
    list_display = ("created_at", "robot", "action_type", "parameters", "status", "sent_at")
    list_filter = ("action_type", "status")
    search_fields = ("robot__name",)
    add_fieldsets = (
        (None, {"fields": ("robot", "action", "map_id", "map_version", "map_download_link", "map_hash")}),
    )
    readonly_fields = ("action_id", "robot", "action_type", "parameters", "status", "sent_at", "created_at")

    def get_fieldsets(self, request: HttpRequest, obj: RobotMapAction | None = None) -> tuple:
        return self.add_fieldsets if obj is None else ((None, {"fields": self.readonly_fields}),)

    def get_readonly_fields(self, request: HttpRequest, obj: RobotMapAction | None = None) -> tuple:
        return () if obj is None else self.readonly_fields

    def has_change_permission(self, request: HttpRequest, obj: RobotMapAction | None = None) -> bool:
        return False  # what the robot reports is not the operator's to edit

    def has_delete_permission(self, request: HttpRequest, obj: RobotMapAction | None = None) -> bool:
        return False

    def save_model(
        self, request: HttpRequest, obj: RobotMapAction, form: MapActionAdminForm, change: bool
    ) -> None:
        queued = robot_map_action(actor=request_actor(request), robot=obj.robot, **form.request_body)
        obj.action_id, obj.action_type, obj.parameters = (
            queued.action_id,
            queued.action_type,
            queued.parameters,
        )
        obj.created_at = queued.created_at
        obj._state.adding = False
