"""`manage.py mcp`: the MCP server over stdio, for desktop clients (agents/stdio.py)."""

from typing import Any

from django.core.management.base import BaseCommand, CommandParser

from agents import stdio


class Command(BaseCommand):
    help = (
        "Serve the MCP tools of a running Mission Dispatch on stdin/stdout, for desktop MCP clients; the "
        f"token comes from ${stdio.TOKEN_VARIABLE}."
    )

    def add_arguments(self, parser: CommandParser) -> None:
        parser.add_argument("--url", help=f"The Mission Dispatch API (default: ${stdio.URL_VARIABLE}).")

    def handle(self, *args: Any, url: str | None, **options: Any) -> None:
        stdio.main([] if url is None else ["--url", url])
