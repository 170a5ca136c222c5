"""The extension zip from tools/build_extension.py installs into a clean Blender and works there.

The install runs in a subprocess: this test process already has the in-repo add-on registered
(conftest.py), so a second copy's operator ids would clash, and bpy is one Blender per process.
The subprocess gets a fresh BLENDER_USER_RESOURCES and sees only what a real Blender ships (bpy,
numpy and bpy's other declared dependencies), not this venv's mujoco and onnxruntime: it runs with
`python -S` and a folder linking just those packages. So mujoco and onnxruntime can only come from
the wheels the zip bundles, and a missing or numpy-less dependency shows up as a failed import.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import os
import platform
import subprocess
import sys
import zipfile
from pathlib import Path
from types import ModuleType

import pytest
from packaging.requirements import Requirement

REPO = Path(__file__).resolve().parents[2]
SHARED = REPO.parent / "shared"
# The zip for the machine the tests run on (Blender's platform names).
HOST_PLATFORM = {
    ("linux", "x86_64"): "linux-x64",
    ("win32", "AMD64"): "windows-x64",
    ("darwin", "arm64"): "macos-arm64",
}.get((sys.platform, platform.machine()))
ADDON_MODULE = "bl_ext.user_default.reactive_anim"
SUBPROCESS_TIMEOUT_S = 600  # install, the first compile of the bundled library and a bake take well under that
WALK_BVH = REPO / "sample_clips" / "walk.bvh"  # 264 frames at 60 fps, keys on frames 1-264

# A two-joint skeleton in centimetres, small enough to read at a glance.
TINY_BVH = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 20 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 20 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
0 90 0 0 0 0 0 0 0
0 90 5 0 10 0 0 5 0
"""

# Runs inside the subprocess: install, inspect, use, uninstall; one JSON line of findings.
INSTALL_SCRIPT = r"""
import hashlib
import json
import os
import sys
import traceback

args = json.loads(sys.argv[1])
sys.path.insert(0, args["runtime"])  # started with -S: only Blender's own packages are importable

import bpy  # noqa: E402  (puts Blender's script folders on sys.path)
import addon_utils  # noqa: E402

found = {}


def user_repo():
    return next(r for r in bpy.context.preferences.extensions.repos if r.module == "user_default")


def installed_function(name):  # the installed package's own bake helpers (blender/bake/bake.py or resources.py)
    for module_name in ("bake.bake", "bake.resources"):
        module = sys.modules.get(args["addon_module"] + ".blender." + module_name)
        if hasattr(module, name):
            return getattr(module, name)
    raise AttributeError("the installed extension has no blender.bake." + name)


def fcurves(action):  # every F-curve, whichever action API this Blender has (4.2, or 4.4+'s layers)
    if getattr(action, "layers", None):
        return [fc for layer in action.layers for strip in layer.strips
                for bag in strip.channelbags for fc in bag.fcurves]
    return list(action.fcurves)


def fingerprint(action):  # F-curve and key counts and a digest of every key: did the action change?
    import numpy

    digest, keys = hashlib.sha256(), 0
    curves = sorted(fcurves(action), key=lambda fc: (fc.data_path, fc.array_index))
    for fc in curves:
        points = fc.keyframe_points
        digest.update("{}[{}]".format(fc.data_path, fc.array_index).encode())
        for name in ("co", "handle_left", "handle_right"):
            values = numpy.empty(len(points) * 2, dtype=numpy.float32)
            points.foreach_get(name, values)
            digest.update(values.tobytes())
        keys += len(points)
    return {"fcurves": len(curves), "keys": keys, "sha256": digest.hexdigest()}


try:
    found["install"] = sorted(bpy.ops.extensions.package_install_files(
        filepath=args["zip"], repo="user_default", enable_on_install=True))
    found["addon_keys"] = sorted(k for k in bpy.context.preferences.addons.keys() if k.endswith("reactive_anim"))
    module = sys.modules.get(args["addon_module"])
    found["addon_file"] = getattr(module, "__file__", None)
    found["operator_idname"] = bpy.ops.reactive_anim.import_bvh.idname()
    found["operator_class"] = hasattr(bpy.types, "REACTIVE_ANIM_OT_import_bvh")
    # Absolute imports of the package would load it a second time under its plain name (or fail).
    found["plain_name_modules"] = sorted(
        k for k in sys.modules if k == "reactive_anim" or k.startswith("reactive_anim."))

    import mujoco
    import numpy
    import onnxruntime

    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='0.1'/></body></worldbody></mujoco>")
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data)
    found["mujoco"] = {"file": mujoco.__file__, "version": mujoco.__version__, "stepped": data.time > 0}
    found["onnxruntime"] = {"file": onnxruntime.__file__, "version": onnxruntime.__version__,
                            "providers": onnxruntime.get_available_providers()}
    found["numpy_file"] = numpy.__file__
    site = os.path.join(bpy.utils.user_resource("EXTENSIONS"), ".local", "lib",
                        "python{}.{}".format(*sys.version_info[:2]), "site-packages")
    found["site_packages"] = site
    found["site_packages_entries"] = sorted(os.listdir(site)) if os.path.isdir(site) else []

    # The installed operator end to end: core BVH reader + Blender's importer, via relative imports.
    found["import_bvh"] = sorted(bpy.ops.reactive_anim.import_bvh(
        filepath=args["bvh"], unit="cm", armature_name="TinyRig"))
    rig = bpy.data.objects.get("TinyRig")
    found["imported_bones"] = len(rig.data.bones) if rig else 0

    # The sample scene with what the zip bundles: the repository's walk, two impacts, and a bake
    # with no library or model given, so the bundled sample library and classifier model.
    found["default_library"] = str(installed_function("default_library_path")())
    found["default_model"] = str(installed_function("default_model_path")())
    found["default_model_exists"] = installed_function("default_model_path")().is_file()
    found["walk_import"] = sorted(bpy.ops.reactive_anim.import_bvh(
        filepath=args["walk_bvh"], unit="auto", armature_name="Walker"))
    walker = bpy.data.objects["Walker"]
    original = walker.animation_data.action
    found["original_action"] = original.name
    first, last = (round(f) for f in original.frame_range)
    found["original_frame_range"] = [first, last]
    found["original_before"] = fingerprint(original)
    rotation_modes = {pb.name: pb.rotation_mode for pb in walker.pose.bones}
    scene = bpy.context.scene
    second = round(scene.render.fps / scene.render.fps_base)
    found["impact_frames"] = [first + second, first + 2 * second]
    found["add_impact"] = [
        sorted(bpy.ops.reactive_anim.add_impact(  # a push from behind (the walk heads along -Y)
            armature_name="Walker", bone="chest", frame=first + second, direction=(0.0, -1.0, 0.0), strength=120.0)),
        sorted(bpy.ops.reactive_anim.add_impact(  # a second later, the hips from the side
            armature_name="Walker", bone="pelvis", frame=first + 2 * second, direction=(1.0, 0.0, 0.0),
            strength=90.0)),
    ]
    found["bake"] = sorted(bpy.ops.reactive_anim.bake(armature_name="Walker"))
    state = walker.reactive_anim_bake
    reacted = state.reacted_action
    found["assigned_after_bake"] = walker.animation_data.action.name
    found["reacted_action"] = reacted.name if reacted else None
    found["reacted_frame_range"] = [round(f) for f in reacted.frame_range] if reacted else None
    found["reacted_keys"] = fingerprint(reacted)["keys"] if reacted else 0
    found["state_original_action"] = state.original_action.name if state.original_action else None
    found["summary"] = state.summary
    found["original_after_bake"] = fingerprint(bpy.data.actions[found["original_action"]])
    # The library the bake opened (open_library() hands back the same compiled one): its clips and cache.
    library = installed_function("open_library")()
    found["library_clip_paths"] = sorted(str(c.path) for c in library.clips)
    found["library_cache"] = str(library.cache_path)
    found["clear_bake"] = sorted(bpy.ops.reactive_anim.clear_bake(armature_name="Walker"))
    found["assigned_after_clear"] = walker.animation_data.action.name
    found["actions_after_clear"] = sorted(a.name for a in bpy.data.actions)
    found["original_after_clear"] = fingerprint(bpy.data.actions[found["original_action"]])
    found["rotation_modes_restored"] = {pb.name: pb.rotation_mode for pb in walker.pose.bones} == rotation_modes
    found["summary_after_clear"] = walker.reactive_anim_bake.summary

    addon_utils.disable(args["addon_module"], default_set=True)
    found["uninstall"] = sorted(bpy.ops.extensions.package_uninstall(
        repo_directory=user_repo().directory, pkg_id="reactive_anim"))
    found["addon_keys_after"] = sorted(k for k in bpy.context.preferences.addons.keys() if k.endswith("reactive_anim"))
    found["operator_class_after"] = hasattr(bpy.types, "REACTIVE_ANIM_OT_import_bvh")
    found["package_dir_after"] = os.path.exists(os.path.join(user_repo().directory, "reactive_anim"))
except Exception:
    found["error"] = traceback.format_exc()
print("RESULT_JSON " + json.dumps(found), flush=True)
"""


def _load_build_tool() -> ModuleType:
    """tools/build_extension.py as a module (tools/ is not a package)."""
    spec = importlib.util.spec_from_file_location("build_extension", REPO / "tools" / "build_extension.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the tool loads
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def build_tool() -> ModuleType:
    return _load_build_tool()


@pytest.fixture(scope="module")
def extension_zip(build_tool: ModuleType) -> Path:
    """This machine's platform zip, rebuilt only when the package, manifest, pins or tool changed."""
    if HOST_PLATFORM is None:
        pytest.skip(f"no extension platform for {sys.platform}/{platform.machine()}")
    path = build_tool.zip_path(build_tool.DEFAULT_DIST, build_tool.read_manifest(), HOST_PLATFORM)
    if not build_tool.is_up_to_date(path):
        build_tool.build([HOST_PLATFORM])
    return path


def _blender_runtime(folder: Path) -> Path:
    """A folder linking bpy and the packages bpy declares (numpy, requests, ...): what Blender ships."""
    folder.mkdir()
    pending, seen = ["bpy"], set()
    while pending:
        dist = importlib.metadata.distribution(pending.pop())
        if dist.metadata["Name"].lower() in seen:
            continue
        seen.add(dist.metadata["Name"].lower())
        for top in {f.parts[0] for f in dist.files or () if f.parts[0] not in ("..", "__pycache__")}:
            source = Path(str(dist.locate_file(top)))
            if source.exists() and not (folder / top).exists():
                (folder / top).symlink_to(source, target_is_directory=source.is_dir())
        for line in dist.requires or ():
            requirement = Requirement(line)
            if requirement.marker is None or requirement.marker.evaluate({"extra": ""}):
                pending.append(requirement.name)
    return folder


@pytest.fixture(scope="module")
def installed(extension_zip: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Findings of installing the zip into a fresh Blender in a subprocess (see INSTALL_SCRIPT)."""
    work = tmp_path_factory.mktemp("extension_install")
    (work / "install.py").write_text(INSTALL_SCRIPT)
    (work / "tiny.bvh").write_text(TINY_BVH)
    user_resources = work / "blender_user"
    user_resources.mkdir()
    args = {
        "runtime": str(_blender_runtime(work / "runtime")),
        "zip": str(extension_zip),
        "bvh": str(work / "tiny.bvh"),
        "walk_bvh": str(WALK_BVH),  # the repository's sample walk: not in the zip
        "addon_module": ADDON_MODULE,
    }
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP")}
    env["BLENDER_USER_RESOURCES"] = str(user_resources)
    completed = subprocess.run(
        [sys.executable, "-S", str(work / "install.py"), json.dumps(args)],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=SUBPROCESS_TIMEOUT_S,
    )
    lines = [line for line in completed.stdout.splitlines() if line.startswith("RESULT_JSON ")]
    output = f"(exit {completed.returncode}):\n{completed.stdout}\n{completed.stderr}"
    assert lines, f"install subprocess printed no result {output}"
    found = json.loads(lines[-1].removeprefix("RESULT_JSON "))
    assert "error" not in found, found["error"] + completed.stderr
    found["user_resources"] = str(user_resources.resolve())
    return found


def _inside(path: str | None, folder: str) -> bool:
    return path is not None and Path(path).resolve().is_relative_to(Path(folder).resolve())


def test_zip_installs_and_enables(installed: dict) -> None:
    assert installed["install"] == ["FINISHED"]
    assert installed["addon_keys"] == [ADDON_MODULE]
    assert _inside(installed["addon_file"], installed["user_resources"]), installed["addon_file"]


def test_operator_registered_by_the_installed_extension(installed: dict) -> None:
    assert installed["operator_idname"] == "REACTIVE_ANIM_OT_import_bvh"
    assert installed["operator_class"]
    assert installed["plain_name_modules"] == [], "the package imported itself by absolute name"


def test_mujoco_and_onnxruntime_come_from_the_bundled_wheels(installed: dict, build_tool: ModuleType) -> None:
    running = "{}.{}".format(*sys.version_info[:2])
    python = next(p for p in build_tool.python_lines() if p.version == running)
    pinned = dict(line.split("==") for line in build_tool.bundle_requirements(python.pins_file))
    for name in ("mujoco", "onnxruntime"):
        module = installed[name]
        assert _inside(module["file"], installed["site_packages"]), f"{name} loaded from {module['file']}"
        assert _inside(module["file"], installed["user_resources"])
        # mujoco may be pinned as the `mujoco` meta package or as `mujoco-core` alone
        assert module["version"] == pinned.get(name, pinned.get(f"{name}-core")), (name, module["version"], pinned)
    assert installed["mujoco"]["stepped"]
    assert "CPUExecutionProvider" in installed["onnxruntime"]["providers"]


def test_numpy_is_blenders_own_not_bundled(installed: dict) -> None:
    assert not _inside(installed["numpy_file"], installed["user_resources"]), installed["numpy_file"]
    bundled_numpy = [e for e in installed["site_packages_entries"] if e.lower().startswith("numpy")]
    assert bundled_numpy == []


def test_installed_operator_imports_a_bvh(installed: dict) -> None:
    assert installed["import_bvh"] == ["FINISHED"]
    assert installed["imported_bones"] == 2


def test_installed_operators_bake_the_sample_walk(installed: dict) -> None:
    assert installed["walk_import"] == ["FINISHED"]
    assert installed["add_impact"] == [["FINISHED"], ["FINISHED"]]
    assert installed["bake"] == ["FINISHED"]
    original = installed["original_action"]
    assert installed["reacted_action"] == f"{original}.reacted"
    assert installed["assigned_after_bake"] == installed["reacted_action"]
    assert installed["state_original_action"] == original
    first, last = installed["original_frame_range"]
    reacted_first, reacted_last = installed["reacted_frame_range"]
    assert reacted_first == first and reacted_last >= last, (installed["reacted_frame_range"], first, last)
    assert installed["reacted_keys"] > 0


def test_bake_used_the_bundled_classifier_model(installed: dict) -> None:
    head, *impact_lines = installed["summary"].splitlines()
    reacted = installed["reacted_action"]
    assert head.startswith(f"'Walker': 2 impacts baked into '{reacted}'"), head
    assert head.split("; ")[1] == "classifier reaction_classifier.onnx", head  # then the frame range, if widened
    assert "no classifier model" not in installed["summary"]
    chest, pelvis = installed["impact_frames"]
    assert len(impact_lines) == 2, impact_lines
    assert impact_lines[0].startswith(f"frame {chest} 'hit_01' chest: "), impact_lines[0]
    assert impact_lines[1].startswith(f"frame {pelvis} 'hit_02' pelvis: "), impact_lines[1]
    assert all("(classifier, p=" in line for line in impact_lines), impact_lines


def test_default_library_and_model_resolve_inside_the_installed_extension(installed: dict) -> None:
    package = str(Path(installed["addon_file"]).parent)
    assert _inside(package, installed["user_resources"]), package
    library, model = installed["default_library"], installed["default_model"]
    assert Path(library).resolve() == Path(package, "sample_library").resolve(), library
    assert Path(model).resolve() == Path(package, "models", "reaction_classifier.onnx").resolve(), model
    assert installed["default_model_exists"]
    # The bake read its clips from there, and cached the compiled library outside the package folder.
    clips = installed["library_clip_paths"]
    assert clips and all(_inside(c, library) for c in clips), clips
    assert _inside(installed["library_cache"], installed["user_resources"]), installed["library_cache"]
    assert not _inside(installed["library_cache"], package), installed["library_cache"]


def test_bake_leaves_the_original_action_unchanged(installed: dict) -> None:
    before = installed["original_before"]
    assert before["fcurves"] > 0 and before["keys"] > 0
    assert installed["original_after_bake"] == before
    assert installed["original_after_clear"] == before


def test_clear_bake_restores_the_original_action(installed: dict) -> None:
    original = installed["original_action"]
    assert installed["clear_bake"] == ["FINISHED"]
    assert installed["assigned_after_clear"] == original
    assert installed["reacted_action"] not in installed["actions_after_clear"]
    assert original in installed["actions_after_clear"]
    assert installed["rotation_modes_restored"]
    assert installed["summary_after_clear"] == ""


def test_uninstall_removes_the_extension(installed: dict) -> None:
    assert installed["uninstall"] == ["FINISHED"]
    assert installed["addon_keys_after"] == []
    assert not installed["operator_class_after"]
    assert not installed["package_dir_after"]


def _shared_bvh_names() -> set[str]:
    return {p.name for p in SHARED.rglob("*.bvh")} if SHARED.is_dir() else set()


def test_zip_validates_and_holds_only_the_addon(extension_zip: Path, build_tool: ModuleType) -> None:
    tool = build_tool.find_blender_ext(None)
    completed = subprocess.run(
        [sys.executable, str(tool), "validate", str(extension_zip)], capture_output=True, text=True
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
    with zipfile.ZipFile(extension_zip) as archive:
        names = archive.namelist()
        manifest = archive.read("blender_manifest.toml").decode()
        library_toml = archive.read("sample_library/library.toml").decode()
    assert "__init__.py" in names and "blender_manifest.toml" in names
    # What the bake needs by default: the sample library (every clip its manifest names) and the model.
    assert "models/reaction_classifier.onnx" in names
    clips = {line.split('"')[1] for line in library_toml.splitlines() if line.startswith("file = ")}
    assert clips and all(f"sample_library/{name}" in names for name in clips), clips
    for name in names:
        parts = name.split("/")
        assert not {"tests", "tools", "__pycache__"} & set(parts), name
        assert not name.endswith(".pyc"), name
    shared_bvh = _shared_bvh_names()
    assert not [n for n in names if n.lower().endswith(".bvh") and n.split("/")[-1] in shared_bvh]
    wheels = [n for n in names if n.startswith("wheels/")]
    assert not [w for w in wheels if w.split("/")[-1].lower().startswith("numpy")]
    # One zip for every supported line: the compiled wheels for each Python those lines embed.
    for python in build_tool.python_lines():
        for package in ("mujoco_core", "onnxruntime"):
            assert [w for w in wheels if w.split("/")[-1].startswith(f"{package}-") and f"-{python.tag}-" in w], (
                package,
                python.tag,
                wheels,
            )
    assert f'platforms = ["{HOST_PLATFORM}"]' in manifest
