"""changes_trim, as beat runs it (fleet.trim_changes): the feed keeps FLEET_CHANGE_RETENTION_SECONDS."""

from datetime import timedelta

from django.conf import settings
from django.utils import timezone

from changes.models import Change, TrimMark
from robots.models import Robot
from tests.factories import RobotFactory
from workers.tasks import trim_changes


def test_changes_older_than_the_retention_window_are_trimmed_and_the_rest_kept(db):
    RobotFactory(name="tt-old")
    Robot.objects.filter(name="tt-old").update(battery_level=5)
    RobotFactory(name="tt-new")
    old = timezone.now() - timedelta(seconds=settings.CHANGE_RETENTION_SECONDS + 60)
    assert Change.objects.filter(name="tt-old").update(created_at=old) == 2
    deleted_xid = Change.objects.get(name="tt-old", image__battery_level=5).xid
    assert not TrimMark.objects.exists()

    assert settings.CELERY_BEAT_SCHEDULE["trim-changes"]["task"] == trim_changes.name
    trim_changes.apply().get()

    assert list(Change.objects.values_list("name", flat=True)) == ["tt-new"]
    # The mark: the newest transaction of a deleted change (GET /events resumes only from after it).
    assert TrimMark.objects.get().xid == deleted_xid
    trim_changes.apply().get()
    assert Change.objects.count() == 1
    assert TrimMark.objects.get().xid == deleted_xid  # nothing deleted: the mark stays
