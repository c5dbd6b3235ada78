"""API tokens (created here, the plaintext is shown once as a message; revoking cannot be undone) and the
write records, read-only."""

from django import forms
from django.contrib import admin, messages
from django.http import HttpRequest
from rest_framework_api_key.admin import APIKeyModelAdmin
from rest_framework_api_key.models import APIKey

from access.models import ApiToken, WriteRecord

# The library's own key model is not used: ApiToken is.
admin.site.unregister(APIKey)


@admin.register(ApiToken)
class ApiTokenAdmin(APIKeyModelAdmin):
    list_display = ("name", "prefix", "read_only", "created", "last_used", "expiry_date", "revoked")
    list_filter = ("read_only", "revoked", "created")
    fields = ("name", "read_only", "expiry_date", "revoked", "prefix", "created", "last_used")

    def get_readonly_fields(self, request: HttpRequest, obj: ApiToken | None = None) -> tuple[str, ...]:
        fields = (*super().get_readonly_fields(request, obj), "created", "last_used")
        # What a token may do is fixed once it exists: a new token is made for other rights.
        return fields if obj is None else (*fields, "read_only")

    def save_model(self, request: HttpRequest, obj: ApiToken, form: forms.ModelForm, change: bool) -> None:
        if change:
            obj.save()
            return
        key = ApiToken.objects.assign_key(obj)
        obj.save()
        self.message_user(
            request,
            f'The new API token "{obj.name}" (store it now: it is never shown again): {key}',
            messages.WARNING,
        )


@admin.register(WriteRecord)
class WriteRecordAdmin(admin.ModelAdmin):
    list_display = ("at", "actor", "action", "object_name", "via")
    list_filter = ("action", "via")
    search_fields = ("actor", "object_name")
    date_hierarchy = "at"

    def has_add_permission(self, request: HttpRequest) -> bool:
        return False

    def has_change_permission(self, request: HttpRequest, obj: WriteRecord | None = None) -> bool:
        return False

    def has_delete_permission(self, request: HttpRequest, obj: WriteRecord | None = None) -> bool:
        return False
