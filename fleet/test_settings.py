"""Settings for the test suite: the same services, but a Redis database of its own.

Tests start real bridge, worker and beat processes; a separate Redis database keeps their Celery queue
and live robot state apart from a development instance (`make run`) on the same machine.
"""

import os

# Before fleet.settings refuses to start without one; the server processes tests start inherit it.
os.environ.setdefault("FLEET_SECRET_KEY", "test-suite-secret-key-not-for-production")

from fleet.settings import *  # noqa: F403
from fleet.settings import env_str

REDIS_URL = env_str("FLEET_TEST_REDIS_URL", "redis://127.0.0.1:6379/9")
CELERY_BROKER_URL = REDIS_URL
WHITENOISE_AUTOREFRESH = True  # serve static files through the finders; no collectstatic before tests
