"""Whether what a request authenticated with still would (`access.selectors.credentials_usable`), as an
open stream's check asks it: each way a token or a session stops authenticating, against the database."""

from datetime import timedelta

import pytest
from django.contrib.auth import HASH_SESSION_KEY
from django.contrib.auth.models import User
from django.contrib.sessions.models import Session
from django.test import Client
from django.utils import timezone

from access.models import ApiToken
from access.selectors import Credential, credentials_usable
from access.services import api_token_create, api_token_revoke

pytestmark = pytest.mark.django_db


def _session(username: str) -> Credential:
    """A staff user's logged-in session, as a stream's request would have taken it."""
    user = User.objects.create_user(username, password="secret-password", is_staff=True)
    browser = Client()
    browser.force_login(user)
    session = browser.session
    return Credential(
        session_key=session.session_key, user_id=str(user.pk), session_hash=session[HASH_SESSION_KEY]
    )


def test_tokens_revoked_or_expired_no_longer_authenticate():
    tokens = {
        name: Credential(token_id=api_token_create(name=name)[0].pk)
        for name in ("kept", "revoked", "expired")
    }
    api_token_revoke(name="revoked")
    ApiToken.objects.filter(name="expired").update(expiry_date=timezone.now() - timedelta(seconds=1))
    assert credentials_usable(set(tokens.values())) == {tokens["kept"]}


def test_sessions_logged_out_expired_demoted_deactivated_or_repassworded_no_longer_authenticate():
    names = ("kept", "logged-out", "expired", "demoted", "deactivated", "new-password")
    sessions = {name: _session(name) for name in names}
    Session.objects.filter(session_key=sessions["logged-out"].session_key).delete()
    Session.objects.filter(session_key=sessions["expired"].session_key).update(expire_date=timezone.now())
    User.objects.filter(username="demoted").update(is_staff=False)
    User.objects.filter(username="deactivated").update(is_active=False)
    user = User.objects.get(username="new-password")
    user.set_password("another-password")
    user.save()
    assert credentials_usable(set(sessions.values())) == {sessions["kept"]}


def test_a_session_of_a_rotated_secret_key_holds_while_the_old_key_is_a_fallback(settings):
    """As Django's own login check: rotating SECRET_KEY with the old one in SECRET_KEY_FALLBACKS keeps the
    sessions logged in; without the fallback they end."""
    session = _session("rotated")
    old_key = settings.SECRET_KEY
    settings.SECRET_KEY = "a-new-secret-key-" + "x" * 50
    settings.SECRET_KEY_FALLBACKS = [old_key]
    assert credentials_usable({session}) == {session}
    settings.SECRET_KEY_FALLBACKS = []
    assert credentials_usable({session}) == set()


def test_many_credentials_are_checked_in_three_queries(django_assert_num_queries):
    credentials = {Credential(token_id=api_token_create(name=f"many-{i}")[0].pk) for i in range(5)}
    credentials |= {_session(f"many-{i}") for i in range(5)}
    with django_assert_num_queries(3):
        assert credentials_usable(credentials) == credentials
