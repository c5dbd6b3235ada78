"""The MCP server (Model Context Protocol): the fleet's tools for AI assistants and agents."""

import warnings

# The SDK's settings model (mcp 1.26) has a field pydantic-settings 2.16 warns about at import; harmless.
warnings.filterwarnings("ignore", message="Field 'lifespan' has an incomplete definition")
