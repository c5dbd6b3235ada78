"""The query filters' base, strict about empty and unstorable values, and the typed filters every list
endpoint shares."""

from typing import Any

import django_filters as filters
from django import forms
from django.conf import settings
from django.db.models import QuerySet


class StrictFilterSet(filters.FilterSet):
    """Query filters that refuse an empty value (`?state=`), which django-filter would take as no filter,
    and a value with a NUL, which some form fields let through and PostgreSQL cannot compare."""

    def is_valid(self) -> bool:
        for name in self.filters:
            values = self.data.getlist(name) if hasattr(self.data, "getlist") else [self.data.get(name)]
            if "" in values:
                self.form.add_error(name, forms.ValidationError("Must not be empty.", code="blank"))
            elif any(isinstance(value, str) and "\x00" in value for value in values):
                error = forms.ValidationError("Must not contain NUL characters.", code="null_characters")
                self.form.add_error(name, error)
        return super().is_valid()


TRUE_WORDS = frozenset({"true", "1", "yes", "on"})
FALSE_WORDS = frozenset({"false", "0", "no", "off"})


class StrictBooleanField(forms.Field):
    """A query boolean that refuses what it cannot read, where Django's would silently ignore the filter."""

    def to_python(self, value: Any) -> bool | None:
        if value in self.empty_values:
            return None
        word = str(value).strip().lower()
        if word in TRUE_WORDS:
            return True
        if word in FALSE_WORDS:
            return False
        raise forms.ValidationError("Must be true or false.", code="invalid")


class StrictBooleanFilter(filters.BooleanFilter):
    field_class = StrictBooleanField


class AnyValueMultipleField(forms.MultipleChoiceField):
    """A repeated query parameter (`?names=a&names=b`) whose values are not limited to a list of choices,
    at most FLEET_API_MAX_FILTER_VALUES of them."""

    def valid_value(self, value: str) -> bool:
        return True

    def validate(self, value: list[str]) -> None:
        super().validate(value)
        if len(value) > settings.API_MAX_FILTER_VALUES:
            raise forms.ValidationError(
                f"At most {settings.API_MAX_FILTER_VALUES} values, not {len(value)}.", code="max_length"
            )


class ValuesInFilter(filters.MultipleChoiceFilter):
    """Keeps the objects whose field equals one of the repeated parameter's values."""

    field_class = AnyValueMultipleField

    def filter(self, qs: QuerySet, value: list[str]) -> QuerySet:
        return qs.filter(**{f"{self.field_name}__in": value}) if value else qs


class FloatFilter(filters.NumberFilter):
    """A number filter on a float column: finite floats, not Decimals."""

    field_class = forms.FloatField
