"""The one error type of the protocol package."""


class ProtocolError(ValueError):
    """A message or topic that does not follow VDA 5050; ``field`` names where, ``reason`` says why."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}")
        self.field = field
        self.reason = reason
