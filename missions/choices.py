"""Django choices of the missions app, built from the vocabulary (``dispatch.vocabulary``).

Each class has the vocabulary enum's names and values, and labels derived from the names as Django does;
use these where Django needs choices (model fields, serializers, filters), the vocabulary elsewhere.
"""

from dispatch import vocabulary
from dispatch.vocabulary import DONE_STATES
from kit.choices import Lifecycle, vocabulary_choices

__all__ = ["DONE_STATES", "FailureCategory", "Lifecycle", "MissionPurpose", "MissionState", "NodeKind"]

MissionState = vocabulary_choices(vocabulary.MissionState)
FailureCategory = vocabulary_choices(vocabulary.FailureCategory)
NodeKind = vocabulary_choices(vocabulary.NodeKind)
MissionPurpose = vocabulary_choices(vocabulary.MissionPurpose)
