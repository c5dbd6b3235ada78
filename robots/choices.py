"""Enumerations of the robots app, spelled as in the reference API (``Lifecycle`` and ``AgvClass`` are the
kit's, which stations share).

``Lifecycle`` and ``RobotState`` are the vocabulary's (``dispatch.vocabulary``) as Django choices: the
vocabulary enum's names and values, and labels derived from the names as Django does.
"""

from django.db import models

from dispatch import vocabulary
from kit.choices import AgvClass as AgvClass
from kit.choices import Lifecycle as Lifecycle
from kit.choices import vocabulary_choices
from vda5050.versions import SUPPORTED_VERSIONS

RobotState = vocabulary_choices(vocabulary.RobotState)


class TeleopAction(models.TextChoices):
    START = "START"
    STOP = "STOP"


class MapAction(models.TextChoices):
    """What an operator may ask a robot to do with a map (VDA 5050 2.1+ instant actions, values as spelled
    on the wire)."""

    DOWNLOAD = "downloadMap", "downloadMap"
    ENABLE = "enableMap", "enableMap"
    DELETE = "deleteMap", "deleteMap"


# The VDA 5050 versions a robot may speak (V2_0_0 = "2.0.0", ...), labelled as spelled.
ProtocolVersion = models.TextChoices(
    "ProtocolVersion",
    [(f"V{version.replace('.', '_')}", (version, version)) for version in SUPPORTED_VERSIONS],
)


class InstantActionsKey(models.TextChoices):
    """Array key of outgoing instantActions messages: the spec's, or the 1.1 name some clients still read
    (labelled as spelled: the admin shows the wire names)."""

    ACTIONS = "actions", "actions"
    INSTANT_ACTIONS = "instantActions", "instantActions"


class SettingSource(models.TextChoices):
    """Where a robot's protocol setting (version, instant actions key) comes from. An operator's choice is
    final; a default gives way to what the robot shows it speaks (LEARNED: its factsheet or topic for the
    version, a compatibility rule for the key)."""

    OPERATOR = "OPERATOR", "OPERATOR"
    DEFAULT = "DEFAULT", "DEFAULT"
    LEARNED = "LEARNED", "LEARNED"


# States from which teleop may be switched on or off.
TELEOP_ALLOWED_STATES = frozenset(
    {RobotState.IDLE, RobotState.ON_TASK, RobotState.MAP_DEPLOYMENT, RobotState.TELEOP}
)
