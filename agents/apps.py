from django.apps import AppConfig


class AgentsConfig(AppConfig):
    """The MCP server (Model Context Protocol): the fleet's tools for AI assistants and agents."""

    name = "agents"
