"""Django choices of the missions app, built from the vocabulary (``dispatch.vocabulary``).

Each class has the vocabulary enum's names and values, and labels derived from the names as Django does;
use these where Django needs choices (model fields, serializers, filters), the vocabulary elsewhere.
"""

from django.db import models

from dispatch import vocabulary
from dispatch.vocabulary import DONE_STATES
from robots.choices import Lifecycle

__all__ = ["DONE_STATES", "FailureCategory", "Lifecycle", "MissionState", "NodeKind"]

MissionState = models.TextChoices("MissionState", [(m.name, m.value) for m in vocabulary.MissionState])
FailureCategory = models.TextChoices(
    "FailureCategory", [(m.name, m.value) for m in vocabulary.FailureCategory]
)
NodeKind = models.TextChoices("NodeKind", [(m.name, m.value) for m in vocabulary.NodeKind])
