"""What every app's admin shares: its writes go through the app's services, and what a service refuses
(a UsageError) is shown to the operator as a message, not as a server error."""

from collections.abc import Callable, Iterable, Iterator, Mapping
from typing import Any, TypeVar

from django import forms
from django.contrib import admin, messages
from django.contrib.admin.utils import model_ngettext
from django.db.models import Model
from django.http import HttpRequest, HttpResponse, HttpResponseRedirect
from django.utils.html import format_html, format_html_join
from django.utils.safestring import SafeString
from rest_framework import serializers

from kit.api.errors import UsageError
from kit.api.names import object_name_validator

M = TypeVar("M", bound=Model)


def html_table(headers: Iterable[str], rows: Iterable[Iterable[object]]) -> SafeString:
    """A read-only list (what a robot reports, what was asked of it, who holds a zone) as a small HTML
    table, escaped."""

    def row(cells: Iterable[object], tag: str) -> SafeString:
        return format_html_join("", f"<{tag}>{{}}</{tag}>", ((cell,) for cell in cells))

    body = format_html_join("", "<tr>{}</tr>", ((row(cells, "td"),) for cells in rows))
    return format_html("<table><tr>{}</tr>{}</table>", row(headers, "th"), body)


def call_service_for_each(
    modeladmin: admin.ModelAdmin,
    request: HttpRequest,
    objects: Iterable[M],
    call: Callable[[M], object],
    done: str,
) -> None:
    """Run an admin action's service on each selected object; the ones it refuses (UsageError) are
    reported together as one warning instead of aborting the rest."""
    accepted = 0
    refusals: list[str] = []
    for obj in objects:
        try:
            call(obj)
        except UsageError as error:
            refusals.append(error.message)
        else:
            accepted += 1
    if accepted:
        noun = model_ngettext(modeladmin.opts, accepted)
        modeladmin.message_user(request, f"{done} for {accepted} {noun}.", messages.SUCCESS)
    if refusals:
        modeladmin.message_user(request, " ".join(refusals), messages.WARNING)


def delete_through_service(
    modeladmin: admin.ModelAdmin,
    request: HttpRequest,
    objects: Iterable[M],
    delete: Callable[[M], M | None],
    until: str,
) -> None:
    """Delete each object with its service; the ones the service only marks PENDING_DELETE (it returns
    them) are named in a message, since the admin's own message says they were deleted."""
    remaining = [str(obj) for obj in objects if delete(obj) is not None]
    if remaining:
        modeladmin.message_user(
            request, f"PENDING_DELETE until {until}: {', '.join(remaining)}.", messages.INFO
        )


def serializer_errors(errors: Any, path: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], str]]:
    """A DRF error tree as (path, message) pairs, e.g. (("battery", "critical_level"), "Must be ...")."""
    if isinstance(errors, Mapping):
        for key, value in errors.items():
            yield from serializer_errors(value, (*path, str(key)))
    elif isinstance(errors, list):
        for error in errors:
            yield from serializer_errors(error, path)
    else:
        yield path, str(errors)


def spec_validated(
    form: forms.ModelForm, serializer_class: type[serializers.Serializer], spec: Mapping[str, Any]
) -> dict[str, Any]:
    """`spec` checked by the API's own spec serializer, so that an admin form accepts exactly what the API
    accepts: its validated data, or {} with each error added to the form field it names (by its path
    joined with "_", or its first step), else to the whole form."""
    serializer = serializer_class(data=spec)
    valid = serializer.is_valid()
    for path, message in serializer_errors(serializer.errors):
        field = next((name for name in ("_".join(path), path[0]) if name in form.fields), None)
        form.add_error(field, message if field else f"{'.'.join(path)}: {message}")
    return serializer.validated_data if valid else {}


class SpecAdminForm(forms.ModelForm):
    """An admin form for an object's spec: its name checked as the API checks names, and `spec`, which the
    subclass's `clean` fills (with `spec_validated`) in the services' shape."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        if "name" in self.fields:
            self.fields["name"].validators.append(object_name_validator)
        self.spec: dict[str, Any] = {}


def pose_text(obj: Any) -> str:
    """An object's pose columns (pose_x, pose_y, pose_theta, pose_map_id) as one short text."""
    where = f" @ {obj.pose_map_id}" if obj.pose_map_id else ""
    return f"({obj.pose_x:.2f}, {obj.pose_y:.2f}, {obj.pose_theta:.2f}){where}"


class ServiceAdmin(admin.ModelAdmin):
    """A model admin whose saves go through services: a save the service refuses (e.g. a VDA 5050
    identity another robot uses, a map action for a 2.0 robot) is shown as an error on the same page, not
    as a server error; the form's transaction is rolled back."""

    def changeform_view(
        self,
        request: HttpRequest,
        object_id: str | None = None,
        form_url: str = "",
        extra_context: Any = None,
    ) -> HttpResponse:
        try:
            return super().changeform_view(request, object_id, form_url, extra_context)
        except UsageError as error:
            self.message_user(request, error.message, messages.ERROR)
            return HttpResponseRedirect(request.get_full_path())

    def delete_model(self, request: HttpRequest, obj: Any) -> None:
        """One object's delete goes the way of a bulk delete: through the subclass's `delete_queryset`,
        which calls the service."""
        self.delete_queryset(request, [obj])
