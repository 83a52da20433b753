"""Simulated bench: plant model, sensors and a device that speaks the wire protocol."""

from tsa_bench.sim.device import MIN_SAMPLING_PERIOD_US, NO_SEGMENT, SimDevice
from tsa_bench.sim.effects import EFFECTS, PlantEffect, PlantInputs, SensorNoise, register_effect
from tsa_bench.sim.identity import SIM_FIRMWARE_VERSION, DeviceLimits, device_limits, identity_message
from tsa_bench.sim.kinematics import TsaGeometry, contracted_length_mm, stretched_length_mm
from tsa_bench.sim.plant import Plant, PlantReading, TsaPlant, plant_from_config
from tsa_bench.sim.sensors import SimSensors

__all__ = [
    "SimDevice", "MIN_SAMPLING_PERIOD_US", "NO_SEGMENT",
    "EFFECTS", "PlantEffect", "PlantInputs", "SensorNoise", "register_effect",
    "SIM_FIRMWARE_VERSION", "DeviceLimits", "device_limits", "identity_message",
    "TsaGeometry", "contracted_length_mm", "stretched_length_mm",
    "Plant", "PlantReading", "TsaPlant", "plant_from_config", "SimSensors",
]
