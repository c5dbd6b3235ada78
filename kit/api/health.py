"""The health endpoint: liveness of the API process."""


from drf_spectacular.utils import (
    OpenApiExample,
    extend_schema,
    inline_serializer,
)
from rest_framework import serializers
from rest_framework.request import Request
from rest_framework.response import Response
from rest_framework.views import APIView

HEALTH_STATUS = "Mission Dispatch: Running"


class HealthView(APIView):
    """Liveness of the API process: public, for load balancers and probes."""

    authentication_classes = []
    permission_classes = []

    @extend_schema(
        operation_id="health",
        summary="Health check",
        tags=["health"],
        responses=inline_serializer("Health", {"status": serializers.CharField()}),
        examples=[OpenApiExample("Running", value={"status": HEALTH_STATUS})],
    )
    def get(self, request: Request) -> Response:
        return Response({"status": HEALTH_STATUS})
