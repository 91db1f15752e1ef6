"""The manufacturers' robot descriptions from the package index, made ready
for Drake.

- Stretch 3: Hello Robot's ``SE3`` URDF with the DW3 wrist and the SG3
  gripper, from the ``hello-robot-stretch-urdf`` package (module
  ``stretch_urdf``).
- UR10: ``ur_description`` from the ``example-robot-data`` package (a cmeel
  data package, no Python module), mounted on our Ridgeback base
  (``models/ridgeback.urdf``; no Ridgeback description is on the index).

Drake refuses STL ``<collision>`` meshes and its Meshcat draws only .obj,
.gltf and .dae, so a description is *prepared* once: collision elements are
dropped (the controller's collision model is the capsule set in models.py),
joints the controller does not move are made fixed, and STL visuals are
converted to decimated .obj files with trimesh. The prepared files go to a
user cache directory (``$SM2ITH_DRAKE_CACHE``, else
``$XDG_CACHE_HOME/sm2ith_drake``, else ``~/.cache/sm2ith_drake``), never into
the installed package; they are made on first use from the installed
packages, without network. Prepared files name meshes either relative to
themselves or as ``package://`` URIs resolved through Drake's PackageMap
(see :func:`AddPackagePaths`), never by absolute path.
"""

from __future__ import annotations

import copy
import hashlib
import importlib.metadata
import importlib.util
import os
import shutil
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import trimesh
from pydrake.multibody.parsing import PackageMap

from sm2ith_drake.resources import GetModelsDir

# Bump when the preparation changes, so stale caches are not reused.
_PREPARE_VERSION = 1

STRETCH_DISTRIBUTION = "hello-robot-stretch-urdf"
UR_DISTRIBUTION = "example-robot-data"
# The package name the ur_description URDFs use in their package:// URIs.
UR_PACKAGE = "example-robot-data"

# Stretch 3 = SE3 body, DW3 wrist, SG3 gripper.
STRETCH3_URDF = "stretch_description_SE3_eoa_wrist_dw3_tool_sg3.urdf"
# Sensor parts left out of the drawing: the head camera's .dae alone is
# 15 MB (a replay embeds every mesh), the gripper camera's STL is in mm.
_STRETCH_OMITTED_MESHES = ("d435.dae", "d405.stl")
# Each STL visual is decimated to at most this many triangles: the drawing
# stays recognizable and a replay of a 20 s run stays a few MB.
_MAX_FACES = 1200


class ModelPackageError(ValueError):
    """A robot description package is missing or unusable (a ValueError, as
    every other unusable robot configuration: the scenario loader turns it
    into a one-line error)."""


def CacheDir() -> Path:
    """Where prepared robot descriptions are kept (created on demand)."""
    if os.environ.get("SM2ITH_DRAKE_CACHE"):
        return Path(os.environ["SM2ITH_DRAKE_CACHE"]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base).expanduser() / "sm2ith_drake"


def _Version(distribution: str) -> str:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError as e:
        raise ModelPackageError(
            f"the robot description package '{distribution}' is not installed "
            f"(pip install {distribution})"
        ) from e


def StretchDescriptionDir() -> Path:
    """The installed ``stretch_urdf/SE3`` directory."""
    _Version(STRETCH_DISTRIBUTION)
    spec = importlib.util.find_spec("stretch_urdf")  # located, not imported
    if spec is None or not spec.submodule_search_locations:
        raise ModelPackageError(f"{STRETCH_DISTRIBUTION}: no stretch_urdf package")
    path = Path(spec.submodule_search_locations[0]).resolve() / "SE3"
    if not (path / STRETCH3_URDF).exists():
        raise ModelPackageError(f"{STRETCH_DISTRIBUTION} has no SE3/{STRETCH3_URDF}")
    return path


def ExampleRobotDataDir() -> Path:
    """The installed ``example-robot-data`` share directory (the root of the
    ``package://example-robot-data/...`` URIs)."""
    _Version(UR_DISTRIBUTION)
    dist = importlib.metadata.distribution(UR_DISTRIBUTION)
    path = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data")))
    if not (path / "robots" / "ur_description").is_dir():
        raise ModelPackageError(f"{UR_DISTRIBUTION} has no robots/ur_description")
    return path.resolve()


def AddPackagePaths(package_map: PackageMap) -> None:
    """Registers the installed description packages with ``package_map``."""
    try:
        path = ExampleRobotDataDir()
    except ModelPackageError:
        return
    if not package_map.Contains(UR_PACKAGE):
        package_map.Add(UR_PACKAGE, str(path))


def _Publish(build, target: Path) -> Path:
    """Runs ``build(tmp_dir)`` and moves the result to ``target`` atomically,
    so a crash or a concurrent process never leaves half a cache."""
    if target.exists():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=target.name + ".", dir=target.parent))
    try:
        build(tmp)
        try:
            tmp.rename(target)
        except OSError:
            if not target.exists():  # not a concurrent winner: a real error
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return target


def _Key(keep_joints, *texts) -> str:
    """A short digest naming one preparation (its inputs)."""
    digest = hashlib.sha256("\n".join(sorted(keep_joints)).encode())
    for text in texts:
        digest.update(text.encode())
    return digest.hexdigest()[:10]


def _StripForDrake(robot: ET.Element, keep_joints) -> None:
    """Drops collision elements, ROS-only tags, and makes every movable joint
    not in ``keep_joints`` fixed (held at its zero position)."""
    for link in robot.findall("link"):
        for collision in link.findall("collision"):
            link.remove(collision)
    for tag in ("transmission", "gazebo"):
        for element in robot.findall(tag):
            robot.remove(element)
    for joint in robot.findall("joint"):
        if joint.get("type") != "fixed" and joint.get("name") not in keep_joints:
            joint.set("type", "fixed")
            for tag in ("axis", "limit", "dynamics", "mimic", "safety_controller"):
                for element in joint.findall(tag):
                    joint.remove(element)


def _ConvertMesh(source: Path, target: Path) -> None:
    mesh = trimesh.load(str(source), force="mesh")
    if len(mesh.faces) > _MAX_FACES:
        mesh = mesh.simplify_quadric_decimation(face_count=_MAX_FACES)
    mesh.export(str(target), file_type="obj", include_normals=False, digits=5)


def PrepareStretch3(keep_joints) -> Path:
    """The Stretch 3 URDF ready for Drake (cached); ``keep_joints`` are the
    URDF joints the controller moves, every other joint is held fixed."""
    source_dir = StretchDescriptionDir()
    version = _Version(STRETCH_DISTRIBUTION)
    name = f"stretch3-SE3-{version}-p{_PREPARE_VERSION}-{_Key(keep_joints)}"

    def build(out: Path):
        robot = ET.parse(source_dir / STRETCH3_URDF).getroot()
        _StripForDrake(robot, set(keep_joints))
        (out / "meshes").mkdir()
        for link in robot.findall("link"):
            for visual in link.findall("visual"):
                mesh = visual.find("geometry/mesh")
                if mesh is None:
                    continue
                filename = mesh.get("filename")
                source = (source_dir / filename).resolve()
                if source.name in _STRETCH_OMITTED_MESHES:
                    link.remove(visual)
                    continue
                obj = out / "meshes" / (source.stem + ".obj")
                if not obj.exists():
                    _ConvertMesh(source, obj)
                mesh.set("filename", f"meshes/{obj.name}")
            for material in link.iter("material"):
                if not material.get("name"):
                    material.set("name", f"{link.get('name')}_color")
        robot.insert(0, ET.Comment(_Provenance(STRETCH_DISTRIBUTION, STRETCH3_URDF)))
        ET.ElementTree(robot).write(out / "stretch3.urdf", encoding="unicode")

    return _Publish(build, CacheDir() / name) / "stretch3.urdf"


def PrepareRidgebackUr10(keep_joints) -> Path:
    """Our Ridgeback base (models/ridgeback.urdf) with the UR10 of
    ``ur_description`` welded to its ``arm_mount`` frame (cached)."""
    ur_urdf = ExampleRobotDataDir() / "robots/ur_description/urdf/ur10_robot.urdf"
    base_urdf = GetModelsDir() / "ridgeback.urdf"
    version = _Version(UR_DISTRIBUTION)
    name = (
        f"ridgeback_ur10-{version}-p{_PREPARE_VERSION}-"
        f"{_Key(keep_joints, base_urdf.read_text())}"
    )

    def build(out: Path):
        robot = ET.parse(base_urdf).getroot()
        ur = ET.parse(ur_urdf).getroot()
        _StripForDrake(ur, set(keep_joints))
        # The UR's own root links would clash with ours ("base_link") or weld
        # it to the world ("world"); rename them and drop the world joint.
        rename = {"base_link": "ur_base_link", "base": "ur_base"}
        for link in ur.findall("link"):
            if link.get("name") == "world":
                ur.remove(link)
            elif link.get("name") in rename:
                link.set("name", rename[link.get("name")])
        for joint in ur.findall("joint"):
            if joint.find("parent").get("link") == "world":
                ur.remove(joint)
                continue
            for tag in ("parent", "child"):
                element = joint.find(tag)
                element.set(
                    "link", rename.get(element.get("link"), element.get("link"))
                )
        for element in ur:
            if element.tag in ("link", "joint", "material"):
                robot.append(copy.deepcopy(element))
        mount = ET.SubElement(robot, "joint", name="ur_mount_joint", type="fixed")
        ET.SubElement(mount, "parent", link="arm_mount")
        ET.SubElement(mount, "child", link="ur_base_link")
        ET.SubElement(mount, "origin", xyz="0 0 0", rpy="0 0 0")
        # The end-effector point: between the fingertips of a gripper on the
        # tool flange, 0.0678 m beyond tool0 (0.16 m from the wrist 3 axis).
        ee = ET.SubElement(robot, "link", name="ee")
        ee_joint = ET.SubElement(robot, "joint", name="ee_fixed_joint_sm2ith")
        ee_joint.set("type", "fixed")
        ET.SubElement(ee_joint, "parent", link="tool0")
        ET.SubElement(ee_joint, "child", link="ee")
        ET.SubElement(ee_joint, "origin", xyz="0 0 0.0678", rpy="0 0 0")
        del ee
        robot.insert(
            0, ET.Comment(_Provenance(UR_DISTRIBUTION, "ur_description ur10_robot"))
        )
        ET.ElementTree(robot).write(out / "ridgeback_ur10.urdf", encoding="unicode")

    return _Publish(build, CacheDir() / name) / "ridgeback_ur10.urdf"


def _Provenance(distribution: str, what: str) -> str:
    return (
        f" Prepared by sm2ith_drake from {what} of the {distribution} "
        f"{_Version(distribution)} package: collision elements removed, "
        "uncontrolled joints fixed, STL visuals converted to .obj. "
    )


PREPARERS = {
    "stretch3": PrepareStretch3,
    "ridgeback_ur10": PrepareRidgebackUr10,
}
