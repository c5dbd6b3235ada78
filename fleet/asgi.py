"""The stream process's ASGI application (`stream` in deploy/Procfile): the watch streams, each an
asyncio task rather than a thread, so hundreds of open streams take none of the API's request threads.
It serves the same URLconf; the REST API itself is served by the WSGI process (fleet.wsgi)."""

import os

from django.core.asgi import get_asgi_application

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")

application = get_asgi_application()
