"""The vocabulary of access: who made a write (an actor) and which write it was."""

from django.db import models

# The actor of a write in open mode (FLEET_API_AUTH=off), where requests carry no identity.
ANONYMOUS = "anonymous"


def token_actor(name: str) -> str:
    return f"token:{name}"


def user_actor(username: str) -> str:
    return f"user:{username}"


def command_actor(command: str) -> str:
    return f"command:{command}"


# WriteRecord.via of a write made through the MCP server's tools (agents/); the API, the admin and the
# commands leave it empty.
VIA_MCP = "mcp"


class WriteAction(models.TextChoices):
    """Every write the API (and the admin) can make; one WriteRecord each."""

    ROBOT_CREATE = "robot_create"
    ROBOT_UPDATE = "robot_update"
    ROBOT_DELETE = "robot_delete"
    ROBOT_TELEOP = "robot_teleop"
    ROBOT_MAP = "robot_map"
    ROBOT_CHARGE = "robot_charge"
    MISSION_CREATE = "mission_create"
    MISSION_CANCEL = "mission_cancel"
    MISSION_UPDATE = "mission_update"
    MISSION_DELETE = "mission_delete"
    STATION_CREATE = "station_create"
    STATION_UPDATE = "station_update"
    STATION_DELETE = "station_delete"
    ZONE_SET_CREATE = "zone_set_create"
    ZONE_SET_ENABLE = "zone_set_enable"
    ZONE_SET_DISABLE = "zone_set_disable"
    ZONE_SET_DELETE = "zone_set_delete"
    ZONE_GRANT_REVOKE = "zone_grant_revoke"
