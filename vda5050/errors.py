"""The error types of the protocol package."""

from enum import StrEnum


class ProtocolError(ValueError):
    """A message or topic that does not follow VDA 5050; ``field`` names where, ``reason`` says why."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}")
        self.field = field
        self.reason = reason


class PayloadProblem(StrEnum):
    """Why a payload is not a JSON object a message can be read from at all."""

    NOT_UTF8 = "not_utf8"
    NOT_JSON = "not_json"
    TOO_DEEP = "too_deep"
    NOT_OBJECT = "not_object"


class PayloadError(ProtocolError):
    """A payload that is no JSON object (``problem`` says which way), before any field is read."""

    def __init__(self, field: str, problem: PayloadProblem, reason: str) -> None:
        super().__init__(field, reason)
        self.problem = problem
