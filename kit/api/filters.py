"""The query filters' base: strict about empty and unstorable values."""


import django_filters as filters
from django import forms


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
