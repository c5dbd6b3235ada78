"""Settings for Mission Dispatch.

Every deployment-specific value comes from an environment variable (documented in README.md) with a
default that works against the services of a local development machine.
"""

import os
from pathlib import Path
from typing import TypeVar

from django.core.exceptions import ImproperlyConfigured

BASE_DIR = Path(__file__).resolve().parent.parent


Number = TypeVar("Number", int, float)


def env_str(name: str, default: str) -> str:
    return os.environ.get(name, default)


def env_int(name: str, default: int) -> int:
    return _env_number(name, default, int, "a whole number")


def env_float(name: str, default: float) -> float:
    return _env_number(name, default, float, "a number")


def _env_number(name: str, default: Number, kind: type[Number], what: str) -> Number:
    """The variable's value, or a start-up error that names it (not a bare ValueError from int())."""
    value = os.environ.get(name)
    if value is None:
        return default
    try:
        return kind(value)
    except ValueError:
        raise ValueError(f"{name} must be {what}, not {value!r}") from None


def env_bool(name: str, default: bool) -> bool:
    value = os.environ.get(name)
    if value is None:
        return default
    return value.strip().lower() in {"1", "true", "yes", "on"}


DEBUG = env_bool("FLEET_DEBUG", False)
# Files `make run` keeps for a development machine (git-ignored): its secret key and its API token.
LOCAL_DIR = Path(env_str("FLEET_LOCAL_DIR", str(BASE_DIR / ".fleet")))
LOCAL_SECRET_KEY_FILE = LOCAL_DIR / "secret-key"
DEV_TOKEN_FILE = LOCAL_DIR / "dev-token"
DEVELOPMENT_SECRET_KEY = "insecure-development-key-change-me-in-production"


def secret_key() -> str:
    """FLEET_SECRET_KEY, else the local key `make run` generated, else (in debug mode only) the built-in
    development key, which anyone can read here and so could forge sessions and CSRF tokens with."""
    key = os.environ.get("FLEET_SECRET_KEY") or (
        LOCAL_SECRET_KEY_FILE.read_text().strip() if LOCAL_SECRET_KEY_FILE.exists() else ""
    )
    if key:
        return key
    if DEBUG:
        return DEVELOPMENT_SECRET_KEY
    raise ImproperlyConfigured(
        "No secret key: set FLEET_SECRET_KEY (e.g. to the output of "
        "python -c 'import secrets; print(secrets.token_urlsafe(50))'). The built-in development key is "
        f"accepted only with FLEET_DEBUG=true; `make run` generates a local key in {LOCAL_SECRET_KEY_FILE}."
    )


SECRET_KEY = secret_key()
ALLOWED_HOSTS = env_str("FLEET_ALLOWED_HOSTS", "*").split(",")

INSTALLED_APPS = [
    "fleetpage",  # before the admin: its admin/base_site.html adds the admin's link to the live fleet page
    "django.contrib.admin",
    "django.contrib.auth",
    "django.contrib.contenttypes",
    "django.contrib.sessions",
    "django.contrib.messages",
    "django.contrib.staticfiles",
    "rest_framework",
    "django_filters",
    "drf_spectacular",
    "drf_spectacular_sidecar",
    "rest_framework_api_key",
    "access",
    "robots",
    "missions",
    "stations",
    "zones",
    "changes",
    "workers",
    "agents",
]

MIDDLEWARE = [
    "django.middleware.security.SecurityMiddleware",
    "kit.api.parsers.body_length_middleware",
    "whitenoise.middleware.WhiteNoiseMiddleware",
    "django.contrib.sessions.middleware.SessionMiddleware",
    "django.middleware.common.CommonMiddleware",
    "django.middleware.csrf.CsrfViewMiddleware",
    "django.contrib.auth.middleware.AuthenticationMiddleware",
    "django.contrib.messages.middleware.MessageMiddleware",
    "django.middleware.clickjacking.XFrameOptionsMiddleware",
]

ROOT_URLCONF = "fleet.urls"

TEMPLATES = [
    {
        "BACKEND": "django.template.backends.django.DjangoTemplates",
        "DIRS": [],
        "APP_DIRS": True,
        "OPTIONS": {
            "context_processors": [
                "django.template.context_processors.request",
                "django.contrib.auth.context_processors.auth",
                "django.contrib.messages.context_processors.messages",
            ],
        },
    },
]

WSGI_APPLICATION = "fleet.wsgi.application"

DATABASES = {
    "default": {
        "ENGINE": "kit.postgresql",
        "NAME": env_str("FLEET_DB_NAME", "mission_dispatch"),
        "USER": env_str("FLEET_DB_USER", "postgres"),
        "PASSWORD": env_str("FLEET_DB_PASSWORD", ""),
        "HOST": env_str("FLEET_DB_HOST", "127.0.0.1"),
        "PORT": env_int("FLEET_DB_PORT", 5432),
        # Persistent connections: no connection setup per request or per task. Each API request checks
        # its connection first (without a query unless the server sent something: `kit.postgresql`),
        # so a PostgreSQL restart never fails a request once the server is back; the hot loops (bridge,
        # steps, tasks) replace a connection only after it failed (`kit.db.drop_broken_connections`).
        "CONN_MAX_AGE": None,
        "CONN_HEALTH_CHECKS": True,
        # Server-side binding lets psycopg prepare the hot statements: PostgreSQL plans them once.
        "OPTIONS": {"server_side_binding": True, "prepare_threshold": 2},
    }
}

DEFAULT_AUTO_FIELD = "django.db.models.BigAutoField"

LANGUAGE_CODE = "en-us"
TIME_ZONE = "UTC"
USE_I18N = True
USE_TZ = True

STATIC_URL = "static/"
STATIC_ROOT = BASE_DIR / "staticfiles"
WHITENOISE_USE_FINDERS = True

# --- REST API -------------------------------------------------------------------------------------
API_PORT = env_int("FLEET_API_PORT", 5000)
# Off: the reference's open API, for trusted networks only (the API process warns at start).
API_AUTH = env_bool("FLEET_API_AUTH", True)
# An API process takes a token it found usable as usable again for this long without asking PostgreSQL (the
# lookup was a round trip per request): a token revoked (by another process) or expired is refused up to
# this late. 0: every request looks it up.
API_TOKEN_CACHE_SECONDS = env_float("FLEET_API_TOKEN_CACHE_SECONDS", 2.0)
# REST requests an API process (fleet.asgi) runs at once, each on a thread of its own that keeps its
# database connection; more wait their turn. Open streams are not counted: they take no thread.
API_THREADS = env_int("FLEET_API_THREADS", 4)
# Streams an API process opens at once (each stream's request: its authentication, filters and snapshot,
# on a database connection let go before the stream's changes flow); more wait their turn. Without a bound,
# hundreds of watchers that connect at once (a restart) would take more connections than PostgreSQL has.
STREAM_OPENINGS = env_int("FLEET_STREAM_OPENINGS", 4)

REST_FRAMEWORK = {
    "DEFAULT_SCHEMA_CLASS": "drf_spectacular.openapi.AutoSchema",
    "DEFAULT_FILTER_BACKENDS": ["django_filters.rest_framework.DjangoFilterBackend"],
    "DEFAULT_RENDERER_CLASSES": ["rest_framework.renderers.JSONRenderer"],
    "DEFAULT_PARSER_CLASSES": ["kit.api.parsers.JSONParser"],
    # Both read FLEET_API_AUTH per request; the first one's WWW-Authenticate makes refusals 401s.
    "DEFAULT_AUTHENTICATION_CLASSES": [
        "access.authentication.BearerTokenAuthentication",
        "access.authentication.StaffSessionAuthentication",
    ],
    "DEFAULT_PERMISSION_CLASSES": ["access.permissions.ApiAccess"],
    "UNAUTHENTICATED_USER": None,
    "EXCEPTION_HANDLER": "kit.api.errors.exception_handler",
}

SPECTACULAR_SETTINGS = {
    "TITLE": "Mission Dispatch API",
    "DESCRIPTION": (
        "Run behaviour-tree missions on fleets of VDA 5050 robots. "
        "Compatible with the public REST API of NVIDIA Isaac Mission Dispatch."
    ),
    "VERSION": "1.0.0",
    "SERVE_INCLUDE_SCHEMA": False,
    # The schema and Swagger UI are public, whatever credentials a request carries.
    "SERVE_AUTHENTICATION": [],
    "SERVE_PERMISSIONS": ["rest_framework.permissions.AllowAny"],
    "SWAGGER_UI_DIST": "SIDECAR",
    "SWAGGER_UI_FAVICON_HREF": "SIDECAR",
    "REDOC_DIST": "SIDECAR",
    "COMPONENT_SPLIT_REQUEST": True,
    # The default hook, then what each app's serializers and filters enforce but cannot state themselves,
    # and the 401/403 answers of the operations that need credentials.
    "POSTPROCESSING_HOOKS": [
        "drf_spectacular.hooks.postprocess_schema_enums",
        "kit.api.schema.names_constraints",
        "missions.api.serializers.schema_constraints",
        "access.schema.add_auth_responses",
    ],
    "ENUM_NAME_OVERRIDES": {
        "RobotStateEnum": "robots.choices.RobotState",
        "MissionStateEnum": "missions.choices.MissionState",
        "SettingSourceEnum": "robots.choices.SettingSource",
        "AgvClassEnum": "robots.choices.AgvClass",
        "MapStatusEnum": "vda5050.models.MapStatus",  # maps and zone sets: ENABLED, DISABLED
    },
}

# --- Streams and the change feed (README "Watching the fleet") -----------------------------------------
# How often an API process reads the change feed for its streams' watchers (the streams' added latency).
WATCH_POLL_SECONDS = env_float("FLEET_WATCH_POLL_SECONDS", 0.2)
# Lines that may wait for one watcher (a client that reads too slowly): one more and it is told and dropped.
WATCH_QUEUE_LINES = env_int("FLEET_WATCH_QUEUE_LINES", 10_000)
# Bytes that may wait for all of a process's watchers together, a change shared by several counted once:
# past it the watchers furthest behind are told and dropped first.
WATCH_QUEUE_BYTES = env_int("FLEET_WATCH_QUEUE_BYTES", 256 * 2**20)
# How often an API process checks that its streams' tokens and sessions still authenticate; a stream whose
# credential no longer does (revoked, expired, logged out) is ended.
STREAM_CREDENTIALS_CHECK_SECONDS = env_float("FLEET_STREAM_CREDENTIALS_CHECK_SECONDS", 10.0)
# How long the change feed keeps a change (beat trims older ones every FLEET_CHANGE_TRIM_SECONDS).
CHANGE_RETENTION_SECONDS = env_float("FLEET_CHANGE_RETENTION_SECONDS", 600.0)
CHANGE_TRIM_SECONDS = env_float("FLEET_CHANGE_TRIM_SECONDS", 60.0)
# GET /events: a comment (with the current resume id) after this long without an event, so proxies keep
# the connection; and the reconnection delay the stream asks of browsers (its `retry:`).
EVENTS_KEEPALIVE_SECONDS = env_float("FLEET_EVENTS_KEEPALIVE_SECONDS", 15.0)
EVENTS_RETRY_SECONDS = env_float("FLEET_EVENTS_RETRY_SECONDS", 2.0)
# Missions the live fleet page (/fleet) loads and keeps at most: the most recent ones, those queued first.
PAGE_MISSIONS = env_int("FLEET_PAGE_MISSIONS", 1000)

# --- API limits: bad input is a 400 that says which limit, never a worker's time or memory -------------
# Read at start (the schema at /openapi.json states them). README.md, "Limits", has what each bounds.
API_MAX_BODY_BYTES = env_int("FLEET_API_MAX_BODY_BYTES", 1_048_576)
DATA_UPLOAD_MAX_MEMORY_SIZE = API_MAX_BODY_BYTES
API_MAX_JSON_DEPTH = env_int("FLEET_API_MAX_JSON_DEPTH", 32)
API_MAX_TREE_NODES = env_int("FLEET_API_MAX_TREE_NODES", 1000)
API_MAX_WAYPOINTS = env_int("FLEET_API_MAX_WAYPOINTS", 1000)
API_MAX_PARAMETERS_BYTES = env_int("FLEET_API_MAX_PARAMETERS_BYTES", 65_536)
API_MAX_TEXT_LENGTH = env_int("FLEET_API_MAX_TEXT_LENGTH", 2048)
API_MAX_LABELS = env_int("FLEET_API_MAX_LABELS", 100)
API_MAX_FILTER_VALUES = env_int("FLEET_API_MAX_FILTER_VALUES", 500)
# Query (and admin form) fields Django parses at most: its default, or the longest filter list plus room
# for every other filter.
DATA_UPLOAD_MAX_NUMBER_FIELDS = max(1000, API_MAX_FILTER_VALUES + 100)

# --- Redis and Celery -----------------------------------------------------------------------------
REDIS_URL = env_str("FLEET_REDIS_URL", "redis://127.0.0.1:6379/0")
CELERY_BROKER_URL = env_str("FLEET_CELERY_BROKER_URL", REDIS_URL)
# kombu's Redis transport with a client reused and a fix for dropped connections (`kit.broker`).
if CELERY_BROKER_URL.partition("://")[0] in ("redis", "rediss"):
    CELERY_BROKER_TRANSPORT = "kit.broker:Transport"
CELERY_TASK_IGNORE_RESULT = True
CELERY_TASK_ACKS_LATE = True
CELERY_TASK_REJECT_ON_WORKER_LOST = True
# A worker reserves no task it cannot run at once: a step a service asked for (`StepPriority.ASKED`) then
# waits behind no reserved routine ones, and the broker's lists show the backlog the bridge holds its
# requests for (`workers.step_requests.HeldSteps`). Prefetch does not change Celery's CPU per task
# (bench/HISTORY.md: 0.99 against 4).
CELERY_WORKER_PREFETCH_MULTIPLIER = env_int("FLEET_CELERY_PREFETCH", 1)
# No task has a rate limit: the worker skips their bookkeeping for every task.
CELERY_WORKER_DISABLE_RATE_LIMITS = True
CELERY_TASK_ALWAYS_EAGER = env_bool("FLEET_CELERY_EAGER", False)
CELERY_BROKER_CONNECTION_RETRY_ON_STARTUP = True
# A worker whose broker (Redis) is away keeps trying to reconnect however long it takes (Celery's default
# gives up after 100 tries, and the worker with it).
CELERY_BROKER_CONNECTION_MAX_RETRIES = None
# Celery's Django fixup closes the database connection around every task unless told to reuse it: that
# would cost a new PostgreSQL backend per task. Reuse it; a broken one is replaced before the next task
# (`fleet.celery`).
CELERY_DB_REUSE_MAX = 1_000_000_000

# --- MQTT and VDA 5050 ----------------------------------------------------------------------------
MQTT_HOST = env_str("FLEET_MQTT_HOST", "127.0.0.1")
MQTT_PORT = env_int("FLEET_MQTT_PORT", 1883)
MQTT_TRANSPORT = env_str("FLEET_MQTT_TRANSPORT", "tcp")
MQTT_WS_PATH = env_str("FLEET_MQTT_WS_PATH", "/mqtt")
MQTT_USERNAME = env_str("FLEET_MQTT_USERNAME", "")
MQTT_PASSWORD = env_str("FLEET_MQTT_PASSWORD", "")
# TLS to the broker (deploy/README.md, "Secured MQTT"): the broker's certificate is checked against the CA
# file (empty: the system's CAs) and, unless turned off, its host name against FLEET_MQTT_HOST.
MQTT_TLS = env_bool("FLEET_MQTT_TLS", False)
MQTT_TLS_CA_FILE = env_str("FLEET_MQTT_TLS_CA_FILE", "")
MQTT_TLS_CHECK_HOSTNAME = env_bool("FLEET_MQTT_TLS_CHECK_HOSTNAME", True)
# A client certificate, for brokers that require one (`require_certificate true`).
MQTT_TLS_CERT_FILE = env_str("FLEET_MQTT_TLS_CERT_FILE", "")
MQTT_TLS_KEY_FILE = env_str("FLEET_MQTT_TLS_KEY_FILE", "")

# Defaults for a new robot's VDA 5050 identity: topic <interface_name>/v<major>/<manufacturer>/<serial>/...
VDA5050_INTERFACE_NAME = env_str("FLEET_VDA5050_INTERFACE_NAME", "uagv")
VDA5050_MANUFACTURER = env_str("FLEET_VDA5050_MANUFACTURER", "RobotCompany")
VDA5050_VERSION = env_str("FLEET_VDA5050_VERSION", "2.0.0")

# `plain`: a line of text per record, on stderr; `json`: a JSON object per line (kit.logs.JsonFormatter)
# on stdout, for container platforms' log collectors.
LOG_FORMAT = env_str("FLEET_LOG_FORMAT", "plain")
if LOG_FORMAT not in {"plain", "json"}:
    raise ImproperlyConfigured(f"FLEET_LOG_FORMAT must be plain or json, not {LOG_FORMAT!r}")
LOGGING = {
    "version": 1,
    "disable_existing_loggers": False,
    "formatters": {
        "plain": {"format": "%(asctime)s %(levelname)s %(name)s: %(message)s"},
        "json": {"()": "kit.logs.JsonFormatter"},
    },
    "handlers": {
        "console": {
            "class": "logging.StreamHandler",
            "stream": "ext://sys.stdout" if LOG_FORMAT == "json" else "ext://sys.stderr",
            "formatter": LOG_FORMAT,
        }
    },
    "root": {"handlers": ["console"], "level": env_str("FLEET_LOG_LEVEL", "INFO")},
    # The MCP SDK logs every request at INFO ("Processing request of type ..."); the access log has them.
    "loggers": {"mcp": {"level": "WARNING"}},
}
# Celery's worker and beat replace the root logger's handlers with their own text format unless told not to.
CELERY_WORKER_HIJACK_ROOT_LOGGER = LOG_FORMAT == "plain"
APPEND_SLASH = False

# --- Dispatch engine ------------------------------------------------------------------------------
# An order the robot's state does not show as accepted after this long is re-sent, identically.
DISPATCH_ORDER_RESEND_SECONDS = env_float("FLEET_ORDER_RESEND_SECONDS", 3.0)
# An instant action the robot has not reported FINISHED/FAILED after this long is re-sent.
DISPATCH_INSTANT_ACTION_RESEND_SECONDS = env_float("FLEET_INSTANT_ACTION_RESEND_SECONDS", 5.0)
# Ask robots for their factsheet when they are created and when they reconnect.
DISPATCH_REQUEST_FACTSHEET = env_bool("FLEET_REQUEST_FACTSHEET", True)
# allowedDeviationXY of an order's first node (the robot's own position), so a strict robot accepts it.
DISPATCH_START_NODE_DEVIATION = env_float("FLEET_START_NODE_DEVIATION", 0.5)
# A robot that took its order (or an order update) and shows no progress on it this long, while not paused,
# in teleop, driving, at a running action or reporting an error, has it canceled and the rest sent as a new
# order (dispatch.faults); 0 turns the check off.
DISPATCH_ORDER_STALL_SECONDS = env_float("FLEET_ORDER_STALL_SECONDS", 30.0)
# How often beat looks for heartbeats, timeouts, deadlines and unacknowledged messages.
DISPATCH_BEAT_PERIOD = env_float("FLEET_BEAT_PERIOD", 1.0)
# How often beat looks for robots that finished their order while their mission did not move on (a step
# lost to a crash); cheap, but it reads every running mission.
DISPATCH_STALL_CHECK_SECONDS = env_float("FLEET_STALL_CHECK_SECONDS", 5.0)
# How often beat runs assignment while unbound missions wait: the safety net under the wake-ups (a new
# unbound mission, a robot freed, created, updated or back online), and the way robots freed otherwise
# (charged, out of teleop) are found.
ASSIGNMENT_CHECK_SECONDS = env_float("FLEET_ASSIGNMENT_CHECK_SECONDS", 3.0)
# How often beat runs the zone plan while a map has an enabled zone set: the longest a zone stays held by a
# robot that fell silent past its heartbeat timeout, or that left the zone without a step noticing.
ZONES_CHECK_SECONDS = env_float("FLEET_ZONES_CHECK_SECONDS", 1.0)
# A burst of unbound missions is bound together once it pauses this long (or once there are as many missions
# as free robots), so that the robots are chosen for all of them at once (dispatch.assignment.burst_hold);
# 0 binds each run's missions at once.
ASSIGNMENT_QUIET_SECONDS = env_float("FLEET_ASSIGNMENT_QUIET_SECONDS", 0.25)
# ... but a stream that never pauses is bound at least this often.
ASSIGNMENT_HOLD_SECONDS = env_float("FLEET_ASSIGNMENT_HOLD_SECONDS", 10.0)
# A robot idle this long (seconds), holding no station, is sent to the nearest free parking station
# (README "Stations: charging and parking"); unset: robots never park by themselves.
DISPATCH_PARK_AFTER_SECONDS = env_float("FLEET_PARK_AFTER_SECONDS", 0.0) or None
# Notify nodes: HTTP POST retries (with exponential backoff) on the reference's retryable statuses.
NOTIFY_RETRIES = env_int("FLEET_NOTIFY_RETRIES", 3)
# The backoff is Celery's (`retry_backoff`), in whole seconds.
NOTIFY_BACKOFF_SECONDS = env_int("FLEET_NOTIFY_BACKOFF_SECONDS", 1)

# --- MQTT bridge ----------------------------------------------------------------------------------
# Slow-changing robot status (pose, battery, ...) is written to PostgreSQL at most this often per robot.
BRIDGE_STATUS_FLUSH_SECONDS = env_float("FLEET_BRIDGE_FLUSH_SECONDS", 1.0)
# MQTT shared-subscription group: several bridges with the same group split the robots' messages.
BRIDGE_SHARE_GROUP = env_str("FLEET_BRIDGE_SHARE_GROUP", "")
# A robot's message larger than this is dropped unparsed (a factsheet with its geometry fits many times over).
MQTT_MAX_PAYLOAD_BYTES = env_int("FLEET_MQTT_MAX_PAYLOAD_BYTES", 1_048_576)
TELEMETRY_SENDER = env_str("FLEET_TELEMETRY_SENDER", "")

# --- Celery queues and beat -----------------------------------------------------------------------
STEP_QUEUE = "steps"
# Robots a step task carries at most: a bridge batch or a sweep that asks for more makes several tasks.
STEP_TASK_ROBOTS = env_int("FLEET_STEP_TASK_ROBOTS", 8)
NOTIFY_QUEUE = "notify"
CELERY_TASK_DEFAULT_QUEUE = STEP_QUEUE
CELERY_BROKER_TRANSPORT_OPTIONS = {"visibility_timeout": env_int("FLEET_VISIBILITY_TIMEOUT", 60)}
CELERY_BEAT_SCHEDULE = {
    "check-heartbeats": {"task": "fleet.check_heartbeats", "schedule": DISPATCH_BEAT_PERIOD},
    "sweep": {"task": "fleet.sweep", "schedule": DISPATCH_BEAT_PERIOD},
    "step-stalled": {"task": "fleet.step_stalled", "schedule": DISPATCH_STALL_CHECK_SECONDS},
    "trim-changes": {"task": "fleet.trim_changes", "schedule": CHANGE_TRIM_SECONDS},
    "assign-waiting": {"task": "fleet.assign_waiting", "schedule": ASSIGNMENT_CHECK_SECONDS},
    "plan-zones": {"task": "fleet.plan_zones_while_enabled", "schedule": ZONES_CHECK_SECONDS},
}
