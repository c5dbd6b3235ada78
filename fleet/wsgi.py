"""The API's WSGI application (Django's WSGI_APPLICATION): the REST API without the streams, which need
the ASGI application (fleet.asgi) that deploy/Procfile serves."""

import os

from django.core.wsgi import get_wsgi_application

from fleet.serving import api_process_start

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "fleet.settings")

application = get_wsgi_application()
api_process_start()
