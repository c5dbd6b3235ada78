"""What an API server process does once, when it loads its application (fleet.asgi, fleet.wsgi)."""

import gc
import logging
from importlib import import_module

from django.conf import settings

# The streams' paths: requests that stay open for as long as the client reads (fleet.asgi).
STREAM_PATHS = frozenset({"/robot/watch", "/mission/watch", "/station/watch", "/zone_set/watch", "/events"})


def api_process_start() -> None:
    """Warn of an open API; load the views and freeze what is loaded.

    What is loaded now lives as long as the worker: the URLconf imports the views and serializers (else the
    first request would), then everything is frozen out of the garbage collector's sight. Unfrozen, the full
    collections walked all of Django every few seconds under load and stopped every request the worker was
    serving meanwhile (bench/HISTORY.md has how long).
    """
    if not settings.API_AUTH:
        logging.getLogger("fleet.api").warning(
            "FLEET_API_AUTH is off: the REST API accepts every request without credentials (the reference's "
            "open API). Use it only on a trusted network."
        )
    import_module(settings.ROOT_URLCONF)
    gc.freeze()
