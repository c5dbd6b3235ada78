"""The stream process's ASGI application (`stream` in deploy/Procfile): the watch streams, each an
asyncio task rather than a thread, so hundreds of open streams take none of the API's request threads.
It serves the same URLconf; the REST API itself is served by the WSGI process (fleet.wsgi)."""

import os

from django.conf import settings
from django.core.asgi import get_asgi_application

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")

application = get_asgi_application()
# Here each request runs in a thread of its own, which ends with it: a persistent connection would outlive
# its thread, open and never used again (Django: "If you're using ASGI, you should disable persistent
# connections"). Closed at each request's end instead; the watch streams' poller keeps its own.
for database in settings.DATABASES.values():
    database["CONN_MAX_AGE"] = 0
