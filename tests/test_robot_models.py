"""The manufacturers' robot models: forward kinematics against
MultibodyPlant on the packaged URDFs, the capsules against the meshes, and
the meshes drawn in Meshcat and in the HTML replay."""

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import trimesh
from browser_shots import CHROMIUM, Screenshot
from pydrake.geometry import GeometrySet, Mesh, Meshcat, Role, SceneGraph
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import PrismaticJoint

from sm2ith_drake.resources import GetDiagramsDir, GetModelsDir
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.robots.packaged import (
    STRETCH3_URDF,
    ExampleRobotDataDir,
    PrepareStretch3,
    StretchDescriptionDir,
)
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import LoadScenario

ROOT = Path(__file__).resolve().parent.parent

# pycollada (trimesh's .dae reader) uses a NumPy idiom NumPy 2.5 deprecates.
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning:collada")

# Grown capsules must contain every mesh vertex (the bound).
COVERAGE_MARGIN_M = 0.03


@pytest.fixture(scope="module")
def stretch():
    return MobileManipulator("stretch3")


@pytest.fixture(scope="module")
def ridgeback():
    return MobileManipulator("ridgeback_ur10")


def _Pose(element):
    origin = element.find("origin")
    xyz = "0 0 0" if origin is None else origin.get("xyz", "0 0 0")
    rpy = "0 0 0" if origin is None else origin.get("rpy", "0 0 0")
    return RigidTransform(
        RollPitchYaw(np.array(rpy.split(), dtype=float)),
        np.array(xyz.split(), dtype=float),
    )


def _OriginalMeshVertices(name):
    """{link: (V, 3) vertices in the link frame} from the manufacturer's own
    visual meshes (not our converted, decimated copies). The Ridgeback is
    ours, boxes and cylinders, and has none; the Stretch's head and gripper
    cameras are left out of the drawing and so of the check."""
    if name == "stretch3":
        root = StretchDescriptionDir()
        urdf = root / STRETCH3_URDF
        rename = {}
    else:
        root = ExampleRobotDataDir()
        urdf = root / "robots/ur_description/urdf/ur10_robot.urdf"
        rename = {"base_link": "ur_base_link"}
    out = {}
    for link in ET.parse(urdf).getroot().findall("link"):
        points = []
        for visual in link.findall("visual"):
            mesh = visual.find("geometry/mesh")
            if mesh is None:
                continue
            filename = mesh.get("filename")
            if filename.endswith(("d435.dae", "d405.stl")):
                continue
            path = root / filename.removeprefix("package://example-robot-data/")
            vertices = np.asarray(trimesh.load(str(path), force="mesh").vertices)
            points.append((_Pose(visual) @ vertices.T).T)
        if points:
            out[rename.get(link.get("name"), link.get("name"))] = np.vstack(points)
    return out


def _ManufacturerPlant(urdf: Path):
    """A MultibodyPlant of the manufacturer's URDF as published, every joint
    left movable; only the geometry is removed (Drake refuses STL collision
    meshes), by this test and not by the code under test."""
    robot = ET.parse(urdf).getroot()
    for link in robot.findall("link"):
        for tag in ("visual", "collision"):
            for element in link.findall(tag):
                link.remove(element)
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModelsFromString(ET.tostring(robot, encoding="unicode"), "urdf")
    plant.Finalize()
    return plant


def _RandomArmQ(robot, rng):
    q = np.zeros(robot.num_positions)
    lo = np.maximum(robot.q_lower[3:], -np.pi)
    hi = np.minimum(robot.q_upper[3:], np.pi)
    q[3:] = rng.uniform(lo, hi)
    return q


def test_stretch3_kinematics_match_the_packaged_urdf(stretch):
    """Our Stretch 3 against a plant of Hello Robot's SE3 URDF as published:
    the four telescope segments each at a quarter of the extension, every
    uncontrolled joint (head, wrist roll, gripper, wheels) at zero."""
    plant = _ManufacturerPlant(StretchDescriptionDir() / STRETCH3_URDF)
    context = plant.CreateDefaultContext()
    movable = [
        plant.get_joint(i)
        for i in plant.GetJointIndices()
        if plant.get_joint(i).num_positions() == 1
    ]
    assert {"joint_head_pan", "joint_wrist_roll", "joint_arm_l2"} <= {
        j.name() for j in movable
    }
    base = plant.GetFrameByName("base_link")
    rng = np.random.default_rng(14)
    for _ in range(50):
        q = _RandomArmQ(stretch, rng)
        lift, extension, yaw, pitch = q[3:]
        for joint in movable:
            value = {
                "joint_lift": lift,
                "joint_wrist_yaw": yaw,
                "joint_wrist_pitch": pitch,
            }.get(joint.name(), 0.0)
            if joint.name().startswith("joint_arm_l"):
                value = extension / 4
            if isinstance(joint, PrismaticJoint):
                joint.set_translation(context, value)
            else:
                joint.set_angle(context, value)
        kin = stretch.CalcKinematics(q)
        ee = plant.GetFrameByName("link_grasp_center").CalcPose(context, base)
        np.testing.assert_allclose(kin.p_WE[0], ee.translation(), atol=1e-9)
        for c, capsule in enumerate(stretch.capsules):
            ends = (
                (capsule.body, capsule.p_A),
                (capsule.body_B or capsule.body, capsule.p_B),
            )
            for e, (body, p) in enumerate(ends):
                X = plant.GetFrameByName(body).CalcPose(context, base)
                np.testing.assert_allclose(
                    kin.capsule_points[0, c, e], X @ np.array(p), atol=1e-9
                )


def test_ur10_kinematics_match_the_packaged_urdf(ridgeback):
    """Our Ridgeback–UR10 against a plant of ur_description's UR10 URDF as
    published, placed at the mount pose of models/ridgeback.urdf."""
    plant = _ManufacturerPlant(
        ExampleRobotDataDir() / "robots/ur_description/urdf/ur10_robot.urdf"
    )
    context = plant.CreateDefaultContext()
    mount = ET.parse(ROOT / "models/ridgeback.urdf").getroot()
    (joint,) = [j for j in mount.findall("joint") if j.get("name") == "arm_mount_joint"]
    X_BaseMount = _Pose(joint)
    ur_base = plant.GetFrameByName("base_link")
    ee_offset = np.array([0.0, 0.0, 0.0678])  # our EE point beyond tool0
    rng = np.random.default_rng(10)
    for _ in range(50):
        q = _RandomArmQ(ridgeback, rng)
        for k, name in enumerate(ridgeback.arm_joint_names):
            plant.GetJointByName(name).set_angle(context, q[3 + k])
        X_UrTool = plant.GetFrameByName("tool0").CalcPose(context, ur_base)
        kin = ridgeback.CalcKinematics(q)
        np.testing.assert_allclose(
            kin.p_WE[0], X_BaseMount @ (X_UrTool @ ee_offset), atol=1e-9
        )


def _CapsuleGap(points, kin, radii):
    """Distance of each point outside the union of the capsules."""
    gap = np.full(len(points), np.inf)
    for c, radius in enumerate(radii):
        a, b = kin.capsule_points[0, c]
        ab = b - a
        t = np.clip((points - a) @ ab / max(ab @ ab, 1e-18), 0.0, 1.0)
        d = np.linalg.norm(points - (a + t[:, None] * ab), axis=1) - radius
        gap = np.minimum(gap, d)
    return gap


@pytest.mark.parametrize("name", ["stretch3", "ridgeback_ur10"])
def test_capsules_cover_every_mesh_vertex(name):
    """Every vertex of the manufacturer's meshes lies inside the robot's
    capsules grown by 3 cm, at the default and 60 random configurations (the
    telescope's segments inside the one capsule that spans it)."""
    robot = MobileManipulator(name)
    plant = robot.plant
    context = plant.CreateDefaultContext()
    vertices = _OriginalMeshVertices(name)
    assert len(vertices) >= (30 if name == "stretch3" else 7)
    rng = np.random.default_rng(3)
    worst = (-np.inf, None)
    for k in range(61):
        q = robot.default_q.copy() if k == 0 else _RandomArmQ(robot, rng)
        if k == 1:
            q[3:] = robot.q_upper[3:].clip(max=np.pi)  # the arm fully out
        kin = robot.CalcKinematics(q)
        plant.SetPositions(context, robot.PlantPositions(q))
        for link, points in vertices.items():
            X = plant.GetBodyByName(link).body_frame().CalcPoseInWorld(context)
            gap = _CapsuleGap((X @ points.T).T, kin, robot.capsule_radii)
            i = int(np.argmax(gap))
            if gap[i] > worst[0]:
                worst = (
                    gap[i],
                    f"{link} vertex {points[i].round(4)} at q={q.round(3)}",
                )
    print(f"{name}: worst vertex {worst[0] * 100:.1f} cm outside: {worst[1]}")
    assert worst[0] <= COVERAGE_MARGIN_M, (
        f"{worst[0] * 100:.1f} cm outside the capsules: {worst[1]}"
    )


@pytest.mark.skipif(
    CHROMIUM is None and not os.environ.get("CI"),
    reason="Debian's chromium is not installed (.ci/run installs it)",
)
@pytest.mark.parametrize(
    "scenario_name, mesh_links",
    [
        ("stretch3_reach", ["link_mast", "link_arm_l0", "link_gripper_s3_body"]),
        ("ridgeback_ur10_reach", ["upper_arm_link", "forearm_link", "wrist_3_link"]),
    ],
)
def test_meshcat_and_replay_draw_the_meshes(scenario_name, mesh_links, tmp_path):
    """The simulation's Meshcat holds the robot's mesh links, and the saved
    replay, opened in a real headless browser, draws the robot (the scene
    differs from an empty viewer's)."""
    assert CHROMIUM is not None, "CI must install chromium"
    scenario = LoadScenario(
        filename=GetDiagramsDir() / "reach.scenarios.yaml",
        scenario_name=scenario_name,
    )
    robot = MobileManipulator(scenario.robot.model)
    # The drawing plant's illustration geometry is the manufacturer's meshes.
    scene_graph = SceneGraph()
    plant = robot.AddToSceneGraph(scene_graph)
    inspector = scene_graph.model_inspector()
    ids = inspector.GetGeometryIds(
        GeometrySet(inspector.GetAllGeometryIds()), Role.kIllustration
    )
    meshes = {
        plant.GetBodyFromFrameId(inspector.GetFrameId(i)).name()
        for i in ids
        if isinstance(inspector.GetShape(i), Mesh)
    }
    assert set(mesh_links) <= meshes
    instance = plant.GetModelInstanceName(
        plant.GetBodyByName("base_link").model_instance()
    )

    meshcat = Meshcat()
    empty_html = tmp_path / "empty.html"
    empty_html.write_text(meshcat.StaticHtml())
    html = tmp_path / "replay.html"
    RunSimulation(scenario, meshcat=meshcat, duration=0.5, html_path=str(html))
    for link in mesh_links:
        assert meshcat.HasPath(f"/drake/visualizer/{instance}/{link}"), link
    # A replay embeds every mesh once; a 20 s run adds only poses.
    assert html.stat().st_size < 16e6
    background = Screenshot(empty_html, tmp_path / "empty.png", tmp_path / "ud1")
    replay = Screenshot(html, tmp_path / "replay.png", tmp_path / "ud2")
    diff = np.abs(replay[40:] - background[40:]).max(axis=-1)
    changed = np.mean(diff > 0.1)
    assert changed > 0.005, f"only {changed:.2%} of the scene differs from background"


def test_prepared_files_go_to_the_user_cache(tmp_path, monkeypatch, stretch):
    """Preparing writes only under $SM2ITH_DRAKE_CACHE (created on first use):
    a URDF without collision elements, with .obj meshes named relative to
    it, no STL and no absolute path."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("SM2ITH_DRAKE_CACHE", str(cache))
    keep = list(stretch.model.arm_joints) + list(stretch.model.coupled_joints)
    urdf = PrepareStretch3(keep)
    assert urdf.is_relative_to(cache) and urdf.exists()
    text = urdf.read_text()
    assert "<collision" not in text and ".STL" not in text and ".stl" not in text
    robot = ET.fromstring(text)
    files = [m.get("filename") for m in robot.iter("mesh")]
    assert files and all(f.startswith("meshes/") and f.endswith(".obj") for f in files)
    assert all((urdf.parent / f).exists() for f in files)
    assert len(list((urdf.parent / "meshes").glob("*.obj"))) >= 30
    assert PrepareStretch3(keep) == urdf  # cached: made once
    shipped = {p.name for p in GetModelsDir().iterdir()}
    assert not any(name.endswith(".obj") for name in shipped)


def test_own_urdf_and_primitive_fallbacks_still_load(tmp_path, ridgeback):
    """robot: {urdf_path: ...}: a URDF of your own, here the prepared UR10
    copied elsewhere (its meshes are package:// URIs, resolved through the
    PackageMap), and the primitive models."""
    own = tmp_path / "my_robot.urdf"
    own.write_text(Path(ridgeback.urdf_path).read_text())
    robot = MobileManipulator("ridgeback_ur10", urdf_path=str(own))
    q = ridgeback.default_q + 0.1
    np.testing.assert_allclose(
        robot.CalcKinematics(q[None]).p_WE, ridgeback.CalcKinematics(q[None]).p_WE
    )
    for name in ("stretch3_primitive", "ridgeback_ur10_primitive"):
        primitive = MobileManipulator(name)
        assert (
            primitive.num_positions
            == MobileManipulator(name.removesuffix("_primitive")).num_positions
        )
    scenario = LoadScenario(
        filename=GetDiagramsDir() / "reach.scenarios.yaml",
        scenario_name="stretch3_reach",
        scenario_text="{robot: {model: stretch3_primitive}}",
    )
    result = RunSimulation(scenario, duration=0.4)
    assert np.isfinite(result.metrics["ee_position.final_error"])


@pytest.mark.parametrize("name", ["stretch3", "ridgeback_ur10"])
def test_drawing_puts_the_end_effector_where_the_model_has_it(name):
    """The plant drawn in Meshcat (AddToSceneGraph, posed by plant_from_q)
    shows the end effector and the base exactly where the controller's model
    has them."""
    robot = MobileManipulator(name)
    plant = robot.AddToSceneGraph(SceneGraph())
    context = plant.CreateDefaultContext()
    ee = plant.GetFrameByName(robot.model.ee_frame)
    rng = np.random.default_rng(8)
    for _ in range(20):
        q = _RandomArmQ(robot, rng)
        q[:3] = rng.uniform(-2, 2, 3)
        plant.SetPositions(context, robot.plant_from_q @ q)
        kin = robot.CalcKinematics(q)
        np.testing.assert_allclose(
            ee.CalcPoseInWorld(context).translation(), kin.p_WE[0], atol=1e-9
        )


def test_stretch_base_radius_contains_the_base_meshes(stretch):
    """base_radius (the disc people see as the robot in their ORCA model)
    contains, in the floor plane, every vertex of the meshes fixed to the
    base: body, wheels, mast, head."""
    plant = stretch.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, stretch.PlantPositions(stretch.default_q))
    base = plant.GetBodyByName("base_link")
    # The lift carries the whole arm: everything it moves is not the base.
    arm = set(
        plant.GetBodiesKinematicallyAffectedBy(
            [plant.GetJointByName("joint_lift").index()]
        )
    )
    checked = 0
    for link, points in _OriginalMeshVertices("stretch3").items():
        body = plant.GetBodyByName(link)
        if body.index() in arm:
            continue
        X = body.body_frame().CalcPose(context, base.body_frame())
        radius = np.linalg.norm((X @ points.T).T[:, :2], axis=1).max()
        assert radius <= stretch.model.base_radius, (link, radius)
        checked += 1
    assert checked >= 10
