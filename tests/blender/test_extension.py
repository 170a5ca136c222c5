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
SUBPROCESS_TIMEOUT_S = 600

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
            source = Path(dist.locate_file(top))
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
    pinned = dict(line.split("==") for line in build_tool.bundle_requirements(build_tool.read_pins()))
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
    assert {"mujoco_core", "onnxruntime"} <= {w.split("/")[-1].split("-")[0] for w in wheels}
    assert f'platforms = ["{HOST_PLATFORM}"]' in manifest
