from typing import Any

from django.conf import settings
from django.core.management.base import BaseCommand, CommandParser

from workers.bridge.loop import Bridge


class Command(BaseCommand):
    help = "Run the MQTT bridge: robots' VDA 5050 messages to Redis and PostgreSQL, steps queued for workers."

    def add_arguments(self, parser: CommandParser) -> None:
        parser.add_argument(
            "--share-group",
            default=settings.BRIDGE_SHARE_GROUP,
            help="MQTT shared-subscription group; bridges in one group split the robots' messages.",
        )

    def handle(self, *args: Any, share_group: str, **options: Any) -> None:
        Bridge(share_group=share_group).run_forever()
