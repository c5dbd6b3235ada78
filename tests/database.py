"""The test database as another process of the server sees it."""

import psycopg
from django.db import connection


def other_connection() -> psycopg.Connection:
    """A connection of its own to the test database: it sees only what this test's connection committed."""
    db = connection.settings_dict
    return psycopg.connect(host=db["HOST"], port=db["PORT"], dbname=db["NAME"], user=db["USER"])
