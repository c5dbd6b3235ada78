"""The Django choices are the vocabulary's: same names and values in the same order, on the classes, the
model fields and the OpenAPI enum overrides."""

from enum import StrEnum

import pytest
from django.conf import settings
from django.db import models
from django.utils.module_loading import import_string

from dispatch import vocabulary
from missions import choices as mission_choices
from missions.models import Mission
from robots import choices as robot_choices
from robots.models import Robot
from stations import choices as station_choices

VOCABULARY = {
    name: enum
    for name, enum in vars(vocabulary).items()
    if isinstance(enum, type) and issubclass(enum, StrEnum) and enum.__module__ == vocabulary.__name__
}


# Every Django choices class of the choices modules named after a vocabulary enum, by its dotted path.
CHOICES = {
    f"{module.__name__}.{name}": value
    for module in (mission_choices, robot_choices, station_choices)
    for name, value in vars(module).items()
    if name in VOCABULARY and isinstance(value, type) and issubclass(value, models.Choices)
}


def test_the_vocabulary_has_the_eight_concepts_and_each_has_its_django_choices():
    assert set(VOCABULARY) == {
        "MissionState",
        "NodeKind",
        "FailureCategory",
        "RobotState",
        "Lifecycle",
        "AgvClass",
        "StationKind",
        "MissionPurpose",
    }
    assert {choices.__name__ for choices in CHOICES.values()} == set(VOCABULARY)


@pytest.mark.parametrize("path", sorted(CHOICES))
def test_django_choices_have_exactly_the_vocabulary_names_and_values(path):
    choices = CHOICES[path]
    enum = VOCABULARY[choices.__name__]
    assert issubclass(choices, models.TextChoices)
    assert choices.names == [member.name for member in enum]
    assert choices.values == [member.value for member in enum]


def test_the_shared_names_are_the_same_objects():
    assert mission_choices.Lifecycle is robot_choices.Lifecycle is station_choices.Lifecycle
    assert robot_choices.AgvClass is station_choices.AgvClass
    assert mission_choices.DONE_STATES is vocabulary.DONE_STATES


@pytest.mark.parametrize(
    ("model", "field", "enum"),
    [
        (Mission, "state", vocabulary.MissionState),
        (Mission, "lifecycle", vocabulary.Lifecycle),
        (Mission, "failure_category", vocabulary.FailureCategory),
        (Robot, "state", vocabulary.RobotState),
        (Robot, "lifecycle", vocabulary.Lifecycle),
    ],
)
def test_model_fields_offer_exactly_the_vocabulary(model, field, enum):
    values = [value for value, _label in model._meta.get_field(field).choices]
    assert values == [member.value for member in enum]


# Overrides of the vocabulary's concepts (others, such as robots' SettingSource, name choice sets that two
# fields share and are not vocabulary).
VOCABULARY_OVERRIDES = sorted(
    path
    for path in settings.SPECTACULAR_SETTINGS["ENUM_NAME_OVERRIDES"].values()
    if path.rsplit(".", 1)[-1] in VOCABULARY
)


@pytest.mark.parametrize("path", VOCABULARY_OVERRIDES)
def test_openapi_enum_overrides_name_vocabulary_choices(path):
    choices = import_string(path)
    assert choices.values == [member.value for member in VOCABULARY[choices.__name__]]


def test_members_are_the_plain_strings_stored():
    # What makes the pure modules' members and the stored plain strings interchangeable.
    for enum in VOCABULARY.values():
        for member in enum:
            assert member == member.value and hash(member) == hash(member.value)
            assert f"{member}" == str(member) == member.value
