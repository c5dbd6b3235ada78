from django.apps import AppConfig


class FleetPageConfig(AppConfig):
    name = "fleetpage"
    verbose_name = "Live fleet page"
