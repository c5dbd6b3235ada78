"""The change feed: one row per write of a robot, mission or station row, written by a trigger in the
writing transaction (migrations 0001, 0003, 0005), whatever wrote it (the ORM, the step's plain SQL, the
bridge's flush, the admin). README "Watch streams" and docs/change-feed.md say why it is built this way."""

from django.db import models

from changes.choices import ChangeKind


class Change(models.Model):
    """A robot's, mission's or station's row as one committed transaction left it (`image`, its columns as
    JSON; a deleted row's last image with lifecycle DELETED).

    `xid` is the writing transaction's id: a reader knows which changes it has seen by the snapshot it
    read them in (a transaction's changes all become visible at its commit), not by `id`, which is taken
    before commit and so is not in commit order.
    """

    id = models.BigAutoField(primary_key=True)
    xid = models.BigIntegerField(help_text="The writing transaction's id (xid8, as pg_current_xact_id()).")
    kind = models.CharField(max_length=10, choices=ChangeKind.choices)
    name = models.CharField(max_length=100)
    image = models.JSONField(help_text="The row's columns after the write.")
    created_at = models.DateTimeField()

    class Meta:
        db_table = "changes_change"
        indexes = [models.Index(fields=["xid"], name="changes_xid")]

    def __str__(self) -> str:
        return f"{self.kind} {self.name} #{self.id}"


class TrimMark(models.Model):
    """How far the trim has deleted (one row, absent until the first trim deleted anything): the newest
    transaction any deleted change came from. A feed position whose snapshot had seen every transaction up
    to this one lost nothing to the trim, so a stream can resume from it (changes.selectors)."""

    id = models.SmallIntegerField(primary_key=True, default=1)
    xid = models.BigIntegerField(help_text="The newest writing transaction (xid8) of a deleted change.")
    trimmed_at = models.DateTimeField()

    class Meta:
        db_table = "changes_trim_mark"

    def __str__(self) -> str:
        return f"trimmed up to xid {self.xid}"
