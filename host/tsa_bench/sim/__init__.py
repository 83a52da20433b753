"""Simulated bench: plant model, sensors and a device that speaks the wire protocol."""

from tsa_bench.sim.device import MIN_SAMPLING_PERIOD_US, NO_SEGMENT, SimDevice
from tsa_bench.sim.effects import EFFECTS, Effect, PlantState, Quantisation, SensorNoise, describe_effects, register_effect
from tsa_bench.sim.history import simulate
from tsa_bench.sim.identity import SIM_FIRMWARE_VERSION, DeviceLimits, device_limits, identity_message
from tsa_bench.sim.kinematics import TsaGeometry, contracted_length_mm, stretched_length_mm
from tsa_bench.sim.plant import Plant, PlantReading, TsaPlant, plant_from_config
from tsa_bench.sim.sensors import SimSensors

__all__ = [
    "SimDevice", "MIN_SAMPLING_PERIOD_US", "NO_SEGMENT",
    "EFFECTS", "Effect", "PlantState", "SensorNoise", "Quantisation", "register_effect", "describe_effects",
    "simulate",
    "SIM_FIRMWARE_VERSION", "DeviceLimits", "device_limits", "identity_message",
    "TsaGeometry", "contracted_length_mm", "stretched_length_mm",
    "Plant", "PlantReading", "TsaPlant", "plant_from_config", "SimSensors",
]
