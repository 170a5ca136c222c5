"""Bake, Preview, Accept, Discard and Clear: the operators behind the panel's buttons.

Bake and Preview compute the same way: invoked from the UI they read the scene on the main thread
(bake.prepare_bake), run the core in a worker thread (worker.BackgroundBake) polled from a
window-manager timer, pass every other event through so Blender stays live, show progress in the
status bar and the panel, and stop on Esc leaving nothing behind. The result is written on the
main thread in the operator's last step, which returns FINISHED: with the UNDO flag the bake is
exactly one undo step (writing data from a timer callback and then undoing is a known crash).
Run from a script, headless or in background mode, the same operators compute synchronously.
"""

# Blender declares operator properties as annotations holding calls (`armature_name: StringProperty(...)`),
# which are not type expressions; pyright is told so for this file only.
# pyright: reportInvalidTypeForm=false

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, cast

import bpy
from bpy.props import StringProperty

from ...core.model.errors import ReactiveAnimError
from ...core.react import Baked
from ..impacts import impact_ops
from ..ui import overlay, settings
from . import bake, preview, worker

if TYPE_CHECKING:
    from bpy._typing.rna_enums import OperatorReturnItems  # fake-bpy-module's name for the result set


def _computable(cls: type[bpy.types.Operator], context: bpy.types.Context) -> bool:
    """Why Bake or Preview cannot run, if it cannot."""
    busy = worker.running()
    if busy is not None:
        cls.poll_message_set(f"Reactions are being computed for '{busy.job.armature}': wait, or press Esc")
        return False
    if context.scene is None or not settings.armatures_with_action():
        in_nla = next((ob for ob in bpy.data.objects if settings.is_character(ob) and settings.nla_strips(ob)), None)
        cls.poll_message_set(
            settings.no_action_message(in_nla) if in_nla else "Select an armature with an action (import a BVH first)"
        )
        return False
    return impact_ops.has_impacts(cls, context)


class _Computes(bpy.types.Operator):
    """What Bake and Preview share: the targets, and computing synchronously or in the background."""

    armature_name: StringProperty(
        name="Armature", description="The armature to react (default: the panel's)", options={"SKIP_SAVE"}
    )
    library_path: StringProperty(
        name="Library",
        description="Reaction library folder or .toml (default: the scene's setting, else the bundled sample library)",
        subtype="FILE_PATH",
        options={"SKIP_SAVE"},
    )
    model_path: StringProperty(
        name="Classifier Model",
        description="ONNX classifier model (default: the scene's setting, else the shipped one)",
        subtype="FILE_PATH",
        options={"SKIP_SAVE"},
    )

    bl_options = {"UNDO"}  # no REGISTER: a redo from Adjust Last Operation would bake again, blocking

    _run: worker.ModalRun | None = None

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _computable(cls, context)

    def write(self, job: bake.BakeJob, baked: Baked, seconds: float) -> bake.BakeResult:
        raise NotImplementedError

    def prepare(self, context: bpy.types.Context) -> bake.BakeJob:
        armature = settings.target_armature(context, self.armature_name)
        scene_settings = settings.scene_settings(context.scene)
        return bake.prepare_bake(
            context.scene,
            armature,
            self.library_path or scene_settings.library_path,
            self.model_path or scene_settings.model_path,
        )

    def execute(self, context: bpy.types.Context) -> set[OperatorReturnItems]:
        """Synchronously: scripts, the command line, background mode."""
        start = time.perf_counter()
        try:
            job = self.prepare(context)
            result = self.write(job, job.run(), time.perf_counter() - start)
        except (ReactiveAnimError, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        for line in result.summary().splitlines():
            self.report({"INFO"}, line)
        return {"FINISHED"}

    def invoke(self, context: bpy.types.Context, event: bpy.types.Event) -> set[OperatorReturnItems]:
        """From the UI: computed in a worker thread, polled from a timer; synchronously where there
        is no event loop (background mode)."""
        if bpy.app.background or context.window is None:
            return self.execute(context)
        workspace = context.workspace
        try:
            background = worker.BackgroundBake(self.prepare(context))
            self._run = worker.ModalRun(
                background, self.write, context.window_manager, context.window,
                status=lambda text: _status(workspace, text), redraw=overlay.tag_redraw,
            )  # fmt: skip
            self._run.start()
        except (ReactiveAnimError, OSError, RuntimeError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context: bpy.types.Context, event: bpy.types.Event) -> set[OperatorReturnItems]:
        assert self._run is not None
        outcome = self._run.handle(event.type, event.value)
        for level, message in outcome.reports:
            self.report({cast(Any, level)}, message)
        return {cast(Any, outcome.result)}

    def cancel(self, context: bpy.types.Context) -> None:
        """Blender ends the operator (a file loaded, the window closed): stop, write nothing."""
        if self._run is not None:
            self._run.cancel()


def _status(workspace: bpy.types.WorkSpace | None, text: str | None) -> None:
    """Status bar text on the workspace the bake started in (Blender sets it on the context's,
    which is another one if the animator switched tabs meanwhile)."""
    if workspace is not None:
        with bpy.context.temp_override(workspace=workspace):
            workspace.status_text_set(text)


class REACTIVE_ANIM_OT_bake(_Computes):
    """Bake the impacts into a new action with the reactions; the original action is kept"""

    bl_idname = "reactive_anim.bake"
    bl_label = "Bake Reactions"

    def write(self, job: bake.BakeJob, baked: Baked, seconds: float) -> bake.BakeResult:
        result = bake.commit_bake(job, baked, seconds)
        preview.discard_preview(settings.armature_named(job.armature))  # a bake supersedes a pending preview
        return result


class REACTIVE_ANIM_OT_preview(_Computes):
    """Compute the reactions and play them on a ghost of the character; the character is not changed"""

    bl_idname = "reactive_anim.preview"
    bl_label = "Preview Reactions"

    def write(self, job: bake.BakeJob, baked: Baked, seconds: float) -> bake.BakeResult:
        return preview.show_preview(job, baked, seconds)


def _some_armature(cls: type[bpy.types.Operator], test: Callable[[bpy.types.Object], bool], message: str) -> bool:
    """Poll: true if some armature passes `test`, else explain."""
    if not any(ob.type == "ARMATURE" and test(ob) for ob in bpy.data.objects):
        cls.poll_message_set(message)
        return False
    return True


class REACTIVE_ANIM_OT_accept_preview(settings.ArmatureOperator):
    """Keep the previewed reactions: they become the character's bake, without computing again"""

    bl_idname = "reactive_anim.accept_preview"
    bl_label = "Accept Preview"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _some_armature(cls, preview.has_preview, "There is no preview to accept: click Preview first")

    def act(self, context: bpy.types.Context, armature: bpy.types.Object) -> str:
        return f"'{armature.name}' plays '{preview.accept_preview(armature, context.scene)}', the accepted preview"


class REACTIVE_ANIM_OT_discard_preview(settings.ArmatureOperator):
    """Remove the preview's ghost and its action"""

    bl_idname = "reactive_anim.discard_preview"
    bl_label = "Discard Preview"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _some_armature(cls, preview.has_preview, "There is no preview to discard")

    def act(self, context: bpy.types.Context, armature: bpy.types.Object) -> str:
        if not preview.discard_preview(armature):
            raise ReactiveAnimError(f"armature '{armature.name}' has no preview to discard")
        return f"Discarded the preview of '{armature.name}'"


def _has_bake(ob: bpy.types.Object) -> bool:
    return bake.bake_state(ob).reacted_action is not None


class REACTIVE_ANIM_OT_clear_bake(settings.ArmatureOperator):
    """Go back to the original action and remove the baked reactions"""

    bl_idname = "reactive_anim.clear_bake"
    bl_label = "Clear Reactions"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _some_armature(cls, _has_bake, "There are no baked reactions to clear")

    def act(self, context: bpy.types.Context, armature: bpy.types.Object) -> str:
        return f"'{armature.name}' plays '{bake.clear_bake(armature)}' again; the reacted action is removed"
