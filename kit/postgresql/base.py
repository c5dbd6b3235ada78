"""Django's PostgreSQL backend whose connection check asks the server only when the socket says something
happened.

Django checks a persistent connection before each request's first query (CONN_HEALTH_CHECKS) with a
`SELECT 1`: a round trip and a statement for PostgreSQL on every API request. A server that ends an idle
connection (a restart, `pg_terminate_backend`, a failover) sends a last message and closes the socket, so
an idle connection with nothing to read is still open; only one with something to read is asked.
"""

import select

from django.db.backends.postgresql import base


class DatabaseWrapper(base.DatabaseWrapper):
    def is_usable(self) -> bool:
        if self.connection is None or self.connection.closed:
            return False
        try:
            readable, _, _ = select.select([self.connection.fileno()], [], [], 0)
        except (OSError, ValueError):  # the socket is gone
            return False
        return not readable or super().is_usable()
