"""The base of every model a scenario is read into (simbench.scenario.schema, a controller's settings in
simbench.api)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, SerializerFunctionWrapHandler, field_serializer, model_validator


class SimbenchModel(BaseModel):
    """Strict, frozen, no unknown fields, no NaN or infinity; lists kept as tuples (written out as lists), so
    that a loaded scenario cannot be changed after it was checked."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)

    @model_validator(mode="after")
    def _freeze_lists(self):
        for name, value in self.__dict__.items():
            if isinstance(value, list):
                object.__setattr__(self, name, tuple(value))
        return self

    @field_serializer("*", mode="wrap")
    def _lists_out(self, value: Any, handler: SerializerFunctionWrapHandler) -> Any:
        return handler(list(value) if isinstance(value, tuple) else value)
