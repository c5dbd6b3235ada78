from django.apps import AppConfig


class AccessConfig(AppConfig):
    name = "access"
    verbose_name = "Access"

    def ready(self) -> None:
        # Registers the OpenAPI extensions of our authentication classes.
        import access.schema  # noqa: F401
