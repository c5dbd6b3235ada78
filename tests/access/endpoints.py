"""Every endpoint of the URLconf, walked from the resolver, so that a new endpoint is checked as soon as it
exists: its concrete path (path parameters filled in) and its HTTP methods."""

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from django.urls import URLPattern, URLResolver, get_resolver

# The only endpoints open without credentials (issue 28): liveness, the Swagger UI and its schema.
PUBLIC_PATHS = frozenset({"/health", "/docs", "/openapi.json"})
# Django's admin has its own login (tests/access/test_session.py covers the API side of sessions), and so
# has the live fleet page, the admin's (tests/fleetpage/test_views.py).
SKIPPED_NAMESPACES = frozenset({"admin", "fleetpage"})
HTTP_METHODS = ("get", "post", "put", "patch", "delete")


@dataclass(frozen=True)
class Endpoint:
    path: str
    method: str

    @property
    def writes(self) -> bool:
        return self.method != "get"

    def __str__(self) -> str:
        return f"{self.method.upper()} {self.path}"


def endpoints(name: str) -> list[Endpoint]:
    """Every (path, method) the API answers, with `name` for every path parameter."""
    found = [
        Endpoint(path, method)
        for path, callback in _patterns(get_resolver().url_patterns, "")
        for method in _methods(callback)
    ]
    return [
        Endpoint(
            "/" + re.sub(r"\(\?P<\w+>[^)]*\)|<[^>]+>", name, endpoint.path.replace("^", "").replace("$", "")),
            endpoint.method,
        )
        for endpoint in found
    ]


def _patterns(patterns: list, prefix: str) -> Iterator[tuple[str, Callable]]:
    for pattern in patterns:
        if isinstance(pattern, URLResolver):
            if pattern.namespace not in SKIPPED_NAMESPACES:
                yield from _patterns(pattern.url_patterns, prefix + str(pattern.pattern))
        elif isinstance(pattern, URLPattern):
            yield prefix + str(pattern.pattern), pattern.callback


def _methods(callback: Callable) -> list[str]:
    actions = getattr(callback, "actions", None)
    if actions is not None:  # a DRF ViewSet: the router's method -> action map
        return [method for method in HTTP_METHODS if method in actions]
    view_class = getattr(callback, "cls", None) or getattr(callback, "view_class", None)
    if view_class is None:
        # A plain function view would be outside DRF's authentication: report it as answering GET, so the
        # tests see it unprotected.
        return ["get"]
    return [method for method in HTTP_METHODS if hasattr(view_class, method)]
