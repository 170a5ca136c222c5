"""The add-on's operators as the tests call them (`addon_ops.bake(armature_name="walk")`), typed.

Blender makes `bpy.ops.reactive_anim` when the add-on registers its operators, so the bpy type stubs
cannot know it; `addon_ops` is that same object, described by the Protocols below: each operator's
own properties as keywords (bake_ops.py, impact_ops.py, role_map.py, operators.py), the execution
context and undo flag positional, as for every Blender operator. A call returns the operator's
result set ({"FINISHED"}, {"CANCELLED"}) or raises RuntimeError with the operator's error report.
Imports bpy: only for tests/blender and tools/demo."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import bpy


class _Operator(Protocol):
    def poll(self, execution_context: str = ..., /) -> bool: ...

    def idname(self) -> str: ...


class _OnArmature(_Operator, Protocol):
    """An operator on one armature (settings.ArmatureOperator): accept/discard preview, clear bake,
    detect and clear roles."""

    def __call__(self, execution_context: str = ..., undo: bool = ..., /, *, armature_name: str = ...) -> set[str]: ...


class _Computes(_Operator, Protocol):
    """Bake and Preview."""

    def __call__(
        self,
        execution_context: str = ...,
        undo: bool = ...,
        /,
        *,
        armature_name: str = ...,
        library_path: str = ...,
        model_path: str = ...,
    ) -> set[str]: ...


class _AddImpact(_Operator, Protocol):
    def __call__(
        self,
        execution_context: str = ...,
        undo: bool = ...,
        /,
        *,
        armature_name: str = ...,
        bone: str = ...,
        frame: int = ...,
        direction_source: str = ...,
        direction: Sequence[float] = ...,
        flatten: bool = ...,
        view_rotation: Sequence[float] = ...,
        strength: float = ...,
        reaction: str = ...,
        marker_name: str = ...,
    ) -> set[str]: ...


class _OnImpact(_Operator, Protocol):
    """Jump to and remove an impact (by uid, else the impact list's active row)."""

    def __call__(self, execution_context: str = ..., undo: bool = ..., /, *, uid: str = ...) -> set[str]: ...


class _AimImpact(_Operator, Protocol):
    def __call__(
        self,
        execution_context: str = ...,
        undo: bool = ...,
        /,
        *,
        uid: str = ...,
        flatten: bool = ...,
        view_rotation: Sequence[float] = ...,
    ) -> set[str]: ...


class _RolePreset(_Operator, Protocol):
    def __call__(
        self, execution_context: str = ..., undo: bool = ..., /, *, armature_name: str = ..., preset: str = ...
    ) -> set[str]: ...


class _ImportBVH(_Operator, Protocol):
    def __call__(
        self,
        execution_context: str = ...,
        undo: bool = ...,
        /,
        *,
        filepath: str = ...,
        unit: str = ...,
        up_axis: str = ...,
        armature_name: str = ...,
    ) -> set[str]: ...


class ReactiveAnimOps(Protocol):
    """`bpy.ops.reactive_anim`: the operators the add-on registers."""

    @property
    def import_bvh(self) -> _ImportBVH: ...
    @property
    def add_impact(self) -> _AddImpact: ...
    @property
    def aim_impact(self) -> _AimImpact: ...
    @property
    def jump_to_impact(self) -> _OnImpact: ...
    @property
    def remove_impact(self) -> _OnImpact: ...
    @property
    def bake(self) -> _Computes: ...
    @property
    def preview(self) -> _Computes: ...
    @property
    def accept_preview(self) -> _OnArmature: ...
    @property
    def discard_preview(self) -> _OnArmature: ...
    @property
    def clear_bake(self) -> _OnArmature: ...
    @property
    def detect_roles(self) -> _OnArmature: ...
    @property
    def role_preset(self) -> _RolePreset: ...
    @property
    def clear_roles(self) -> _OnArmature: ...


_MODULE = "reactive_anim"  # the bl_idname prefix of every operator of the add-on

# bpy.ops makes an operator module on attribute access and finds the operator only when it is called,
# so this one object serves before and after the add-on registers.
addon_ops: ReactiveAnimOps = getattr(bpy.ops, _MODULE)
