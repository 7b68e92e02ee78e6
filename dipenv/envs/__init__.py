"""Environment classes (registered by ``import dipenv``)."""

from dipenv.envs.field_control import FieldControlEnv, FieldMagnitudeEnv, FieldVectorEnv

__all__ = ["FieldControlEnv", "FieldMagnitudeEnv", "FieldVectorEnv"]
