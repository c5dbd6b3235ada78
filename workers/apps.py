from django.apps import AppConfig


class WorkersConfig(AppConfig):
    name = "workers"

    def ready(self) -> None:
        """Domain services ask for steps through `fleet.wake`; here they become Celery step tasks."""
        from fleet import wake
        from workers.steps import request_steps_soon

        wake.install(request_steps_soon)
