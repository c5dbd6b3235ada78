from rest_framework.routers import SimpleRouter

from zones.api.views import ZoneSetViewSet

# /zone_set, /zone_set/{name}, /zone_set/{name}/enable, /zone_set/{name}/revoke, /zone_set/watch: no trailing
# slashes, as /station.
router = SimpleRouter(trailing_slash=False)
router.register("zone_set", ZoneSetViewSet, basename="zone_set")

urlpatterns = router.urls
