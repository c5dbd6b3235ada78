from django.urls import path

from fleetpage.views import fleet_page

# A namespace of its own: a page behind the admin's login, not an API endpoint (tests/access skips it).
app_name = "fleetpage"
urlpatterns = [
    path("fleet", fleet_page, name="fleet"),
]
