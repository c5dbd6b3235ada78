"""Database parameters the project's plain-SQL hot paths share."""

import json
from typing import Any

import orjson
from psycopg.types.json import Jsonb


def jsonb(value: Any) -> Jsonb:
    """`value` as a jsonb parameter, serialized by orjson: Django's adapter uses the json module, which
    takes several times longer on a mission's tree and node status (the API's and the steps' hot paths)."""
    return Jsonb(value, dumps=_json_bytes)


def _json_bytes(value: Any) -> bytes:
    try:
        return orjson.dumps(value, option=orjson.OPT_NON_STR_KEYS)
    except orjson.JSONEncodeError:  # what orjson refuses and json takes: integers beyond 64 bits
        return json.dumps(value).encode()
