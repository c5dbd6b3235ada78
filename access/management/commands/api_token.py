"""API tokens from the command line: create (prints the token once, alone on the last line), list, revoke,
and `dev`, the development token `make run` keeps in a git-ignored file."""

from pathlib import Path
from typing import Any

from django.conf import settings
from django.core.management.base import BaseCommand, CommandError, CommandParser

from access.selectors import api_token_list
from access.services import api_token_create, api_token_revoke, dev_token_ensure
from kit.api.errors import UsageError


class Command(BaseCommand):
    help = "Create, list and revoke API tokens (clients send them as Authorization: Bearer <token>)."

    def add_arguments(self, parser: CommandParser) -> None:
        commands = parser.add_subparsers(dest="action", required=True)
        create = commands.add_parser("create", help="Create a token and print it (only this once).")
        create.add_argument("name", help="Who uses the token; writes are recorded under this name.")
        create.add_argument("--read-only", action="store_true", help="The token may only read.")
        commands.add_parser("list", help="List the tokens (never their plaintext).")
        revoke = commands.add_parser("revoke", help="Revoke a token: it is refused from now on.")
        revoke.add_argument("name")
        dev = commands.add_parser("dev", help="Print the development token, creating it once.")
        dev.add_argument("--file", type=Path, default=settings.DEV_TOKEN_FILE, help="Where it is kept.")

    def handle(self, *args: Any, action: str, **options: Any) -> None:
        try:
            getattr(self, f"_{action}")(**options)
        except UsageError as error:
            raise CommandError(error.message) from error

    def _create(self, *, name: str, read_only: bool, **options: Any) -> None:
        token, key = api_token_create(name=name, read_only=read_only)
        scope = "read-only" if token.read_only else "read-write"
        self.stdout.write(f'Created the {scope} API token "{token.name}". It is shown only now:')
        self.stdout.write(key)

    def _list(self, **options: Any) -> None:
        rows = [("name", "access", "created", "last used", "revoked")]
        for token in api_token_list():
            rows.append(
                (
                    token.name,
                    "read-only" if token.read_only else "read-write",
                    f"{token.created:%Y-%m-%d %H:%M}",
                    f"{token.last_used:%Y-%m-%d %H:%M}" if token.last_used else "never",
                    "revoked" if token.revoked else "",
                )
            )
        widths = [max(len(row[column]) for row in rows) for column in range(len(rows[0]))]
        for row in rows:
            cells = (cell.ljust(width) for cell, width in zip(row, widths, strict=True))
            self.stdout.write("  ".join(cells).rstrip())

    def _revoke(self, *, name: str, **options: Any) -> None:
        api_token_revoke(name=name)
        self.stdout.write(f'Revoked the API token "{name}".')

    def _dev(self, *, file: Path, **options: Any) -> None:
        key = dev_token_ensure(path=file)
        port = settings.API_PORT
        self.stdout.write(
            f"Development API token: {key}\n"
            f"It is kept in {file}; clients send it as Authorization: Bearer <token>:\n"
            f"  export TOKEN=$(cat {file})\n"
            f'  curl -H "Authorization: Bearer $TOKEN" localhost:{port}/robot\n'
            f"Swagger UI: http://localhost:{port}/docs (Authorize, paste the token).\n"
            f"MCP server for AI assistants: http://localhost:{port}/mcp, the same token (README, MCP server)."
        )
