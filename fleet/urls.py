from django.contrib import admin
from django.urls import include, path
from drf_spectacular.views import SpectacularJSONAPIView, SpectacularSwaggerView

from fleet.events import EventsView
from kit.api.health import HealthView
from missions.api.views import BehaviorsView
from workers.metrics import MetricsView

urlpatterns = [
    path("admin/", admin.site.urls),
    path("", include("fleetpage.urls")),
    path("openapi.json", SpectacularJSONAPIView.as_view(), name="openapi"),
    path("docs", SpectacularSwaggerView.as_view(url_name="openapi"), name="docs"),
    path("health", HealthView.as_view(), name="health"),
    path("behaviors", BehaviorsView.as_view(), name="behaviors"),
    path("metrics", MetricsView.as_view(), name="metrics"),
    path("events", EventsView.as_view(), name="events"),
    path("", include("robots.api.urls")),
    path("", include("missions.api.urls")),
    path("", include("stations.api.urls")),
    path("", include("zones.api.urls")),
]
