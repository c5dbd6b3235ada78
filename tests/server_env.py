"""The settings our server processes run with in the tests that start them (tests/e2e, tests/faults): time
compressed, so that beats, resends and retries happen within a test's patience."""

SERVER_ENV = {
    "FLEET_BEAT_PERIOD": "0.2",
    "FLEET_ORDER_RESEND_SECONDS": "1.0",
    "FLEET_INSTANT_ACTION_RESEND_SECONDS": "1.0",
    "FLEET_BRIDGE_FLUSH_SECONDS": "0.2",
    "FLEET_VISIBILITY_TIMEOUT": "5",
    "FLEET_STREAM_CREDENTIALS_CHECK_SECONDS": "1.0",
    "FLEET_LOG_LEVEL": "INFO",
    "FLEET_SECRET_KEY": "test-server-secret-key-not-for-production",
}
