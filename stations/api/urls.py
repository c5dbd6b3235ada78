from rest_framework.routers import SimpleRouter

from stations.api.views import StationViewSet

# /station, /station/{name}, /station/watch: no trailing slashes, as /robot and /mission.
router = SimpleRouter(trailing_slash=False)
router.register("station", StationViewSet, basename="station")

urlpatterns = router.urls
