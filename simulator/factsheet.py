"""The factsheet a simulated robot publishes: its class, limits and the actions of ``simulator.actions``."""

from __future__ import annotations

from simulator.actions import ACTION_SPECS, CHARGING_ACTIONS, ZONE_SET_ACTIONS
from simulator.config import RobotConfig, RobotType, SimulationSettings
from vda5050.models import (
    AgvAction,
    AgvClass,
    AgvGeometry,
    AgvKinematic,
    FactsheetActionParameter,
    FactsheetContent,
    LoadSpecification,
    LocalizationType,
    MaxArrayLens,
    MaxStringLens,
    NavigationType,
    OptionalParameter,
    ParameterSupport,
    PhysicalParameters,
    ProtocolFeatures,
    ProtocolLimits,
    Timing,
    TypeSpecification,
    VehicleConfig,
    VersionInfo,
)
from vda5050.versions import MAJOR_3, V2_0, major_of
from vda5050.zones import ZoneType

SERIES_NAME = "Mission Dispatch simulated robot"
PLACEHOLDER_CLASS = AgvClass.CARRIER  # stands in for classes the 2.x enum lacks, patched on the wire
SUPPORTED_OPTIONAL_PARAMETERS = (
    "order.nodes.nodePosition.theta",
    "order.nodes.nodePosition.allowedDeviationXY",
    "order.nodes.nodePosition.allowedDeviationTheta",
    "order.edges.maxSpeed",
)
SIMULATOR_SOFTWARE_VERSION = "1.0.0"
SUPPORTED_ZONES = [ZoneType.RELEASE.value]  # 3.0: the zone type the robot heeds (simulator.zones)


def factsheet_content(config: RobotConfig, settings: SimulationSettings, version: str) -> FactsheetContent:
    """A complete factsheet of ``version``; in 2.x, MANIPULATOR/HUMANOID get a placeholder agvClass (see
    PLACEHOLDER_CLASS); 3.0's class is free text."""
    is_3 = major_of(version) >= MAJOR_3
    charges = config.battery_rates(settings)[1] > 0  # else it lists no startCharging/stopCharging
    standard_classes = {agv_class.value for agv_class in AgvClass}
    agv_class: AgvClass | str = (
        AgvClass(config.robot_type.value)
        if config.robot_type in standard_classes
        else config.robot_type.value
        if is_3
        else PLACEHOLDER_CLASS
    )
    speed_max = 0.0 if config.robot_type == RobotType.MANIPULATOR else settings.speed
    return FactsheetContent(
        type_specification=TypeSpecification(
            series_name=SERIES_NAME,
            series_description=f"Simulated {config.robot_type.value.lower()} (Mission Dispatch simulator)",
            agv_kinematic=AgvKinematic.OMNI,
            agv_class=agv_class,
            max_load_mass=100.0,
            localization_types=[LocalizationType.NATURAL],
            navigation_types=[NavigationType.AUTONOMOUS],
            supported_zones=SUPPORTED_ZONES if is_3 else None,
        ),
        physical_parameters=PhysicalParameters(
            speed_min=0.0,
            speed_max=speed_max,
            acceleration_max=1.0,
            deceleration_max=1.0,
            height_min=0.3,
            height_max=0.3,
            width=0.6,
            length=0.8,
        ),
        protocol_limits=ProtocolLimits(
            max_string_lens=MaxStringLens(),
            max_array_lens=MaxArrayLens(),
            timing=Timing(
                min_order_interval=0.0,
                min_state_interval=0.0,
                default_state_interval=settings.state_period,
                visualization_interval=settings.visualization_period or None,
            ),
        ),
        protocol_features=ProtocolFeatures(
            optional_parameters=[
                OptionalParameter(parameter=parameter, support=ParameterSupport.SUPPORTED)
                for parameter in SUPPORTED_OPTIONAL_PARAMETERS
            ],
            agv_actions=[
                AgvAction(
                    action_type=str(spec.action_type),
                    action_description=spec.description,
                    action_scopes=list(spec.scopes),
                    action_parameters=[
                        FactsheetActionParameter(
                            key=parameter.key,
                            value_data_type=parameter.value_data_type,
                            description=parameter.description,
                            is_optional=parameter.is_optional,
                        )
                        for parameter in spec.parameters
                    ]
                    or None,
                    pause_allowed=False if is_3 else None,  # required in 3.0
                    cancel_allowed=True if is_3 else None,
                )
                for spec in ACTION_SPECS
                if (charges or spec.action_type not in CHARGING_ACTIONS)
                and (is_3 or spec.action_type not in ZONE_SET_ACTIONS)
            ],
        ),
        agv_geometry=AgvGeometry(),
        load_specification=LoadSpecification(),
        localization_parameters={} if version == V2_0 else None,
        vehicle_config=(
            VehicleConfig(versions=[VersionInfo(key="simulator", value=SIMULATOR_SOFTWARE_VERSION)])
            if version != V2_0
            else None
        ),
    )
