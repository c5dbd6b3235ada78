from rest_framework.routers import SimpleRouter

from robots.api.views import RobotViewSet

# /robot, /robot/{name}, /robot/{name}/teleop: no trailing slashes, as in the reference.
router = SimpleRouter(trailing_slash=False)
router.register("robot", RobotViewSet, basename="robot")

urlpatterns = router.urls
