"""Enumerations of the zones app: VDA 5050 3.0's zone vocabulary (``vda5050.zones``) as Django choices."""

from kit.choices import Lifecycle, vocabulary_choices
from vda5050 import zones

__all__ = [
    "BidirectedLimitation",
    "DirectedLimitation",
    "Lifecycle",
    "ReleaseLossBehavior",
    "ZoneActionBlockingType",
    "ZoneType",
]

ZoneType = vocabulary_choices(zones.ZoneType)
ReleaseLossBehavior = vocabulary_choices(zones.ReleaseLossBehavior)
DirectedLimitation = vocabulary_choices(zones.DirectedLimitation)
BidirectedLimitation = vocabulary_choices(zones.BidirectedLimitation)
ZoneActionBlockingType = vocabulary_choices(zones.ZoneActionBlockingType)
