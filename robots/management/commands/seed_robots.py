"""Create a set of robots with default specs, e.g. for a demo or a simulator run."""

from typing import Any

from django.core.management.base import BaseCommand, CommandError, CommandParser

from access.choices import command_actor
from kit.api.errors import UsageError
from robots.models import Robot
from robots.services import robot_create

# Numbered names are zero-padded to at least this many digits: carter01, carter02, ...
MIN_NUMBER_DIGITS = 2


def numbered_names(prefix: str, count: int) -> list[str]:
    digits = max(MIN_NUMBER_DIGITS, len(str(count)))
    return [f"{prefix}{number:0{digits}d}" for number in range(1, count + 1)]


class Command(BaseCommand):
    help = (
        "Create robots with the default spec, named explicitly or <prefix>01..<prefix>N. "
        "Robots that already exist are skipped, so running it again changes nothing."
    )

    def add_arguments(self, parser: CommandParser) -> None:
        parser.add_argument("names", nargs="*", help="Names of the robots to create.")
        parser.add_argument(
            "--count", type=int, help="Create this many robots named <prefix>01, <prefix>02, ..."
        )
        parser.add_argument("--prefix", default="carter", help="Name prefix for --count (default: carter).")

    def handle(self, *args: Any, names: list[str], count: int | None, prefix: str, **options: Any) -> None:
        if names and count is not None:
            raise CommandError("Give either robot names or --count, not both.")
        if not names and count is None:
            raise CommandError("Give robot names or --count N.")
        if count is not None and count < 1:
            raise CommandError("--count must be at least 1.")
        wanted = list(dict.fromkeys(names)) or numbered_names(prefix, count)
        existing = set(Robot.objects.filter(name__in=wanted).values_list("name", flat=True))
        for name in wanted:
            if name in existing:
                self.stdout.write(f"Skipped {name}: already exists.")
                continue
            try:
                robot_create(actor=command_actor("seed_robots"), name=name, prefix=None, spec={})
            except UsageError as error:
                raise CommandError(error.message) from error
            self.stdout.write(self.style.SUCCESS(f"Created {name}."))
        self.stdout.write(f"{len(wanted) - len(existing)} created, {len(existing)} skipped.")
