"""The vocabulary's (``dispatch.vocabulary``) concepts that several apps share, as Django choices: the enum's
names and values, and labels derived from the names as Django does."""

from enum import StrEnum

from django.db import models

from dispatch import vocabulary


def vocabulary_choices(enum: type[StrEnum]) -> type[models.TextChoices]:
    """The Django choices of a vocabulary enum, named as it is."""
    return models.TextChoices(enum.__name__, [(member.name, member.value) for member in enum])


Lifecycle = vocabulary_choices(vocabulary.Lifecycle)
# A robot's type (VDA 5050 factsheet `typeSpecification.agvClass`): robots filter on it as `robot_type`,
# stations list the types they serve.
AgvClass = vocabulary_choices(vocabulary.AgvClass)
