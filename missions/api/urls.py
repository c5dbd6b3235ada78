from rest_framework.routers import SimpleRouter

from missions.api.views import MissionViewSet

# /mission, /mission/{name}, /mission/{name}/cancel, /mission/{name}/update: no trailing slashes.
router = SimpleRouter(trailing_slash=False)
router.register("mission", MissionViewSet, basename="mission")

urlpatterns = router.urls
