"""The API's WSGI application, as granian serves it (`deploy/Procfile`)."""

import gc
import logging
import os
from importlib import import_module

from django.conf import settings
from django.core.wsgi import get_wsgi_application

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")

application = get_wsgi_application()

if not settings.API_AUTH:
    logging.getLogger("fleet.api").warning(
        "FLEET_API_AUTH is off: the REST API accepts every request without credentials (the reference's "
        "open API). Use it only on a trusted network."
    )

# What is loaded now lives as long as the worker: the URLconf imports the views and serializers (else the
# first request would), then everything is frozen out of the garbage collector's sight. Unfrozen, the full
# collections walked all of Django every few seconds under load and stopped every request the worker was
# serving meanwhile (bench/README.md has how long).
import_module(settings.ROOT_URLCONF)
gc.freeze()
