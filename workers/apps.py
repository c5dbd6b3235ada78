from django.apps import AppConfig


class WorkersConfig(AppConfig):
    name = "workers"

    def ready(self) -> None:
        """Domain services ask for steps, assignment and zone plan runs through `kit.wake`; here they become
        Celery tasks."""
        from kit import wake
        from workers.step_requests import queue_assignment_soon, queue_steps_soon, queue_zones_plan_soon

        wake.install(queue_steps_soon, queue_assignment_soon, queue_zones_plan_soon)
