"""The live fleet page (GET /fleet): one HTML page for a logged-in staff user; everything on it comes from the
API's server-sent events (GET /events) and goes back through the REST API with the same session."""

from django.conf import settings
from django.contrib.admin.views.decorators import staff_member_required
from django.http import HttpRequest, HttpResponse, QueryDict
from django.shortcuts import render
from django.urls import reverse

from dispatch.vocabulary import DONE_STATES, MissionState

# Stands for an object's name in the URL templates the page fills in (no name can make it appear twice:
# the template is filled, not the name).
NAME = "__name__"


@staff_member_required
def fleet_page(request: HttpRequest) -> HttpResponse:
    """The page and what its script needs to know: where the events and the API's actions are, and the
    mission states to filter by; and the login to send the operator to once the session has ended."""
    config = {
        "events_url": reverse("events"),
        "mission_snapshot": settings.PAGE_MISSIONS,
        "mission_list_url": reverse("mission-list"),
        "mission_cancel_url": reverse("mission-cancel", kwargs={"name": NAME}),
        "robot_teleop_url": reverse("robot-teleop", kwargs={"name": NAME}),
        "name_placeholder": NAME,
        "mission_states": list(MissionState),
        "done_states": sorted(DONE_STATES),
    }
    return render(request, "fleetpage/fleet.html", {"config": config, "login_url": _login_url()})


def _login_url() -> str:
    """The admin's login, back to this page after it (as staff_member_required sends anonymous visitors)."""
    query = QueryDict(mutable=True)
    query["next"] = reverse("fleetpage:fleet")
    return f"{reverse('admin:login')}?{query.urlencode(safe='/')}"
