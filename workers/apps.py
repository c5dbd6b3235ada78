from django.apps import AppConfig


class WorkersConfig(AppConfig):
    name = "workers"

    def ready(self) -> None:
        """Domain services ask for steps through `kit.wake`; here they become Celery step tasks."""
        from kit import wake
        from workers.step_requests import queue_steps_soon

        wake.install(queue_steps_soon)
