"""The maps a simulated robot has (VDA 5050 2.1+ reports them in ``maps``), the one it is on, and its
downloads: downloadMap, enableMap and deleteMap as 2.1 section 6.7 and its action table describe them."""

from __future__ import annotations

from simulator.actions import DOWNLOAD_MAP_SECONDS, ActionRun, UnusableAction, parameters_of, require
from simulator.config import SimulationSettings
from simulator.errors import ACTION_ERROR, DUPLICATE_MAP, UNKNOWN_MAP, ErrorReport, Rejection
from simulator.outbox import Outbox
from vda5050.maps import MAP_DOWNLOAD_LINK, MAP_ID, MAP_VERSION
from vda5050.models import ActionStatus, ActionType, Map, MapStatus, Order

FIRST_MAP_VERSION = "1"  # the version of the map a robot starts on (and of one it switches to)


class RobotMaps:
    """mapId -> {mapVersion: status}; the robot starts with its map enabled."""

    def __init__(
        self,
        map_id: str,
        *,
        has_maps: bool,
        settings: SimulationSettings,
        errors: ErrorReport,
        outbox: Outbox,
    ) -> None:
        self.map_id = map_id  # the map the robot is on
        self._has_maps = has_maps
        self._settings = settings
        self._errors = errors
        self._outbox = outbox
        self._maps: dict[str, dict[str, MapStatus]] = {map_id: {FIRST_MAP_VERSION: MapStatus.ENABLED}}
        self._downloads: list[tuple[ActionRun, float]] = []  # (downloadMap, when it is done)

    def report(self) -> list[Map] | None:
        """The state's ``maps`` (2.1+)."""
        if not self._has_maps:
            return None
        return [
            Map(map_id=map_id, map_version=version, map_status=status)
            for map_id, versions in self._maps.items()
            for version, status in versions.items()
        ]

    def check_order(self, order: Order) -> None:
        """A 2.1+ robot drives only on maps it has enabled (the master must see to that, 2.1 section 6.7)."""
        if not self._has_maps:
            return
        for node in order.nodes:
            map_id = node.node_position.map_id if node.node_position else None
            if map_id is not None and MapStatus.ENABLED not in self._maps.get(map_id, {}).values():
                raise Rejection(UNKNOWN_MAP, f"node {node.node_id!r} is on map {map_id!r}, not enabled")

    def localize_on(self, map_id: str) -> None:
        """Switch to `map_id` (load_map, initPosition): a map the robot switches to is one it has, enabled."""
        self.map_id = map_id
        versions = self._maps.setdefault(map_id, {})
        if MapStatus.ENABLED not in versions.values():
            versions[max(versions, default=FIRST_MAP_VERSION)] = MapStatus.ENABLED
        self._outbox.state_changed = True

    def act(self, run: ActionRun, now: float) -> None:
        """downloadMap, enableMap or deleteMap."""
        parameters = parameters_of(run.action)
        try:
            map_id, version = (str(require(parameters, key)) for key in (MAP_ID, MAP_VERSION))
            if run.action.action_type == ActionType.DOWNLOAD_MAP:
                require(parameters, MAP_DOWNLOAD_LINK)
        except UnusableAction as exc:
            self._errors.refuse_action(run, ACTION_ERROR, str(exc))
            return
        versions = self._maps.get(map_id, {})
        match run.action.action_type:
            case ActionType.DOWNLOAD_MAP:
                downloading = any(
                    parameters_of(d.action).get(MAP_ID) == map_id
                    and str(parameters_of(d.action).get(MAP_VERSION)) == version
                    for d, _ in self._downloads
                )
                if version in versions or downloading:
                    self._errors.refuse_action(run, DUPLICATE_MAP, f"map {map_id} {version} is already here")
                    return
                run.status = ActionStatus.RUNNING
                seconds = 0.0 if self._settings.completes_instantly else DOWNLOAD_MAP_SECONDS
                self._downloads.append((run, now + seconds))
                self.finish_downloads(now)
            case _ if version not in versions:
                self._errors.refuse_action(run, UNKNOWN_MAP, f"map {map_id} {version} is not here")
            case ActionType.ENABLE_MAP:
                self._maps[map_id] = {
                    v: MapStatus.ENABLED if v == version else MapStatus.DISABLED for v in versions
                }
                run.finish(f"map {map_id} {version} enabled")
            case ActionType.DELETE_MAP:
                del versions[version]
                if not versions:
                    del self._maps[map_id]
                run.finish(f"map {map_id} {version} deleted")

    def finish_downloads(self, now: float) -> None:
        """Downloads whose time is up: the map is there, DISABLED, and the downloadMap FINISHED."""
        done = [(run, at) for run, at in self._downloads if at <= now]
        for run, _ in done:
            parameters = parameters_of(run.action)
            map_id, version = str(parameters[MAP_ID]), str(parameters[MAP_VERSION])
            self._maps.setdefault(map_id, {})[version] = MapStatus.DISABLED
            run.finish(f"map {map_id} {version} downloaded")
            self._outbox.state_changed = True
        self._downloads = [entry for entry in self._downloads if entry not in done]
