"""Enumerations of the stations app: the vocabulary's (``dispatch.vocabulary``) as Django choices."""

from dispatch import vocabulary
from kit.choices import AgvClass, Lifecycle, vocabulary_choices

__all__ = ["AgvClass", "Lifecycle", "StationKind"]

StationKind = vocabulary_choices(vocabulary.StationKind)
