from django.db import models


class ChangeKind(models.TextChoices):
    ROBOT = "robot"
    MISSION = "mission"
    STATION = "station"
    ZONE_SET = "zone_set"
