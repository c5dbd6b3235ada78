"""API tokens (stored hashed: SHA-512 of a random key, by djangorestframework-api-key) and the record of
every write, with who made it."""

from django.db import models
from django.db.models import Q
from django.utils import timezone
from rest_framework_api_key.models import AbstractAPIKey

from access.choices import WriteAction

TOKEN_NAME_MAX_LENGTH = 50
ACTOR_MAX_LENGTH = 200
# What the admin's token form says when a usable token has the name already (Django's own message names
# the constraint).
DUPLICATE_NAME = "A usable token has this name already: revoke it first or pick another name."


class ApiToken(AbstractAPIKey):
    """A client's credential for the REST API. The plaintext is shown once, at creation; the row keeps only
    its prefix (to find it) and its hash. Revoking cannot be undone."""

    name = models.CharField(
        max_length=TOKEN_NAME_MAX_LENGTH,
        help_text="Who uses the token (unique among usable tokens); writes are recorded under it.",
    )
    read_only = models.BooleanField(default=False, help_text="The token may only read (GET), never write.")
    last_used = models.DateTimeField(null=True, blank=True, editable=False)

    class Meta(AbstractAPIKey.Meta):
        verbose_name = "API token"
        verbose_name_plural = "API tokens"
        constraints = [
            models.UniqueConstraint(
                fields=["name"],
                condition=Q(revoked=False),
                name="api_token_name_unique_while_usable",
                violation_error_message=DUPLICATE_NAME,
            )
        ]


class WriteRecord(models.Model):
    """One write through the API or the admin: what, on which object, by whom, when. Stored in the same
    transaction as the write itself."""

    at = models.DateTimeField(default=timezone.now, db_index=True)
    actor = models.CharField(
        max_length=ACTOR_MAX_LENGTH, db_index=True, help_text="token:<name>, user:<username> or anonymous."
    )
    action = models.CharField(max_length=32, choices=WriteAction.choices)
    object_name = models.CharField(max_length=100, help_text="The robot or mission written.")
    via = models.CharField(
        max_length=16,
        blank=True,
        default="",
        help_text="mcp for a write through the MCP server's tools; empty for the API, the admin, a command.",
    )

    class Meta:
        ordering = ["-at", "-id"]

    def __str__(self) -> str:
        return f"{self.action} {self.object_name} by {self.actor}"
