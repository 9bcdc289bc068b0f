"""VRM 1.0 avatars and VRM animation clips: the Khronos validator clean, the VRM T-pose by the numbers, the
avatar posed by the clip (re-evaluated here with pygltflib + NumPy) equal to the model's skinning, and
three-vrm + three-vrm-animation (npm) in headless Chromium resolving the humanoid and posing the avatar."""

from __future__ import annotations

import functools
import http.server
import io
import shutil
import threading
import warnings

import numpy as np
import pytest

pytest.importorskip("pygltflib", reason="the export extra (pygltflib) is not installed")

import smplcore
from export_helpers import (
    GlbReader,
    issues,
    make_motion,
    node_package,
    open_model,
    validate,
    without_correctives,
)
from smplcore.export.vrm import HUMAN_BONES, REQUIRED_BONES, humanoid_bones, save_vrm, save_vrma, vrm_tpose

pytestmark = pytest.mark.filterwarnings(
    "ignore:.*pose.correctives.*:UserWarning",
    "ignore:.*no bone for.*:UserWarning",
    "ignore:.*another shape space.*:UserWarning",
)

OPEN_BONES = sorted(
    [
        "hips", "spine", "chest", "upperChest", "neck", "head",
        *(f"{s}{b}" for s in ("left", "right")
          for b in ("UpperLeg", "LowerLeg", "Foot", "Toes", "Shoulder", "UpperArm", "LowerArm", "Hand")),
    ]
)  # fmt: skip


def _motion(model_type: str = "smpl", seconds: float = 1.0):
    """A test motion whose non-humanoid joints (SMPL's hand joints) stay at rest: a VRM clip drops them."""
    motion = make_motion(model_type, seconds=seconds, fps=30.0, num_betas=10)
    if model_type == "smpl":
        motion.poses[:, 66:72] = 0.0
    return motion


@pytest.fixture(scope="module")
def open_files(tmp_path_factory):
    model = open_model(num_betas=10)
    motion = _motion()
    folder = tmp_path_factory.mktemp("vrm")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        avatar = save_vrm(folder / "open.vrm", model, motion)
        clip = save_vrma(folder / "walk.vrma", model, motion)
    return model, motion, folder / "open.vrm", folder / "walk.vrma", avatar, clip


@pytest.fixture(scope="module")
def smplx_files(tmp_path_factory, fake_models):
    """SMPL-X (fake file: its fingers' rest directions are far from the T-pose) with a motion of every joint."""
    model = smplcore.BodyModel(fake_models["smplx_neutral_npz"], use_pca=False, flat_hand_mean=True, num_betas=10)
    motion = make_motion("smplx", seconds=0.5, fps=30.0, num_betas=10)
    folder = tmp_path_factory.mktemp("vrm-smplx")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        save_vrm(folder / "x.vrm", model, motion)
        save_vrma(folder / "x.vrma", model, motion)
    return model, motion, folder / "x.vrm", folder / "x.vrma"


def test_humanoid_map_of_every_body_model(fake_models):
    names = open_model().skeleton_joint_names
    assert sorted(humanoid_bones(names)) == OPEN_BONES
    smplx = smplcore.BodyModel(fake_models["smplx_neutral_npz"])
    bones = humanoid_bones(smplx.skeleton_joint_names)
    assert len(bones) == len(OPEN_BONES) + 3 + 30  # jaw, eyes, 15 finger bones per hand
    assert {"jaw", "leftEye", "rightEye", "leftThumbMetacarpal", "rightLittleDistal"} <= set(bones)
    # the VRM parent of every bone is the nearest mapped ancestor in our tree (VRM humanoid.md's hierarchy)
    parents = smplx.parents
    vrm_parent = {"spine": "hips", "chest": "spine", "upperChest": "chest", "neck": "upperChest", "head": "neck",
                  "leftShoulder": "upperChest", "leftUpperArm": "leftShoulder", "leftHand": "leftLowerArm",
                  "leftIndexProximal": "leftHand", "leftThumbProximal": "leftThumbMetacarpal",
                  "leftToes": "leftFoot", "rightUpperLeg": "hips", "jaw": "head"}  # fmt: skip
    by_joint = {j: b for b, j in bones.items()}
    for bone, parent in vrm_parent.items():
        assert by_joint[parents[bones[bone]]] == parent, bone
    with pytest.raises(ValueError, match="VRM humanoid needs"):
        humanoid_bones(["head", "jaw"])
    assert set(REQUIRED_BONES) <= set(HUMAN_BONES.values())


def test_validator_clean(open_files):
    _, _, vrm, vrma, _, _ = open_files
    for path in (vrm, vrma):
        report = validate(path)
        assert report["issues"]["numErrors"] == 0, issues(report)
        assert report["issues"]["numWarnings"] == 0, issues(report, 1)
        unsupported = {m["message"].split("'")[1] for m in issues(report, 2) if m["code"] == "UNSUPPORTED_EXTENSION"}
        assert unsupported == {"VRMC_vrm" if path.suffix == ".vrm" else "VRMC_vrm_animation"}
    info = validate(vrm)["info"]
    assert info["hasSkins"] and info["maxInfluences"] == 4 and info["animationCount"] == 0


def test_vrm_extension_and_meta(open_files):
    model, _, vrm, vrma, avatar, _ = open_files
    gltf = GlbReader(vrm).gltf
    ext = gltf.extensions["VRMC_vrm"]
    assert ext["specVersion"] == "1.0" and gltf.extensionsUsed == ["VRMC_vrm"]
    meta = ext["meta"]
    assert meta["licenseUrl"] == "https://vrm.dev/licenses/1.0/"
    assert meta["otherLicenseUrl"] == "https://creativecommons.org/publicdomain/zero/1.0/"
    assert meta["allowRedistribution"] is True and meta["authors"] == ["smplcore"]
    bones = ext["humanoid"]["humanBones"]
    assert sorted(bones) == OPEN_BONES
    names = {v: k for k, v in HUMAN_BONES.items()}
    assert all(gltf.nodes[b["node"]].name == names[bone] for bone, b in bones.items())
    assert gltf.nodes[bones["leftUpperArm"]["node"]].name == "left_shoulder"
    anim_ext = GlbReader(vrma).gltf.extensions["VRMC_vrm_animation"]
    assert anim_ext["specVersion"] == "1.0" and sorted(anim_ext["humanoid"]["humanBones"]) == OPEN_BONES
    assert avatar.format == "vrm" and avatar.file_size == vrm.stat().st_size


def test_licensed_model_meta_states_the_users_licence(fake_models, tmp_path):
    model = smplcore.BodyModel(fake_models["smplx_neutral_npz"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        save_vrm(tmp_path / "x.vrm", model, meta={"name": "me", "authors": ["A. Person"]})
    gltf = GlbReader(tmp_path / "x.vrm").gltf
    meta = gltf.extensions["VRMC_vrm"]["meta"]
    assert meta["name"] == "me" and meta["authors"] == ["A. Person"]
    assert meta["otherLicenseUrl"] == "https://smpl-x.is.tue.mpg.de/modellicense.html"
    assert meta["allowRedistribution"] is False and meta["modification"] == "prohibited"
    assert meta["commercialUsage"] == "personalNonProfit" and "licence its user accepted" in meta["thirdPartyLicenses"]
    assert len(gltf.extensions["VRMC_vrm"]["humanoid"]["humanBones"]) == 55  # every SMPL-X joint is a VRM bone
    report = validate(tmp_path / "x.vrm")
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, issues(report, 1)


def _world_positions(reader: GlbReader) -> dict[str, np.ndarray]:
    world = reader.world_matrices(0)
    return {node.name: world[i, :3, 3] for i, node in enumerate(reader.gltf.nodes)}


def test_rest_is_the_vrm_tpose(open_files, fake_models):
    _, _, vrm, _, _, _ = open_files
    reader = GlbReader(vrm)
    pos = _world_positions(reader)
    verts = reader.skinned_vertices(0)  # the avatar at rest, as viewers show it
    assert abs(verts[:, 1].min()) < 1e-6  # soles on y = 0
    np.testing.assert_allclose(pos["pelvis"][[0, 2]], 0.0, atol=1e-7)
    turned = {n.name for n in reader.gltf.nodes if n.rotation is not None}  # rest rotations: the T-pose
    assert turned == {f"{s}_{j}" for s in ("left", "right") for j in ("shoulder", "elbow", "wrist")}
    for side, sign in (("left", 1.0), ("right", -1.0)):  # arms straight along +X (left) / -X (right)
        chain = [pos[f"{side}_{j}"] for j in ("shoulder", "elbow", "wrist", "hand")]
        for a, b in zip(chain[:-1], chain[1:], strict=True):
            d = (b - a) / np.linalg.norm(b - a)
            np.testing.assert_allclose(d, [sign, 0.0, 0.0], atol=1e-6)
    # the nose side of the head is at +Z: the body faces +Z
    head = verts[verts[:, 1] > pos["head"][1]]
    assert head[:, 2].max() > -head[:, 2].min() - 0.02
    # SMPL-X: fingers along X, thumbs at 45 degrees between X and +Z
    smplx = smplcore.BodyModel(fake_models["smplx_neutral_npz"])
    rest = np.asarray(smplx.rest_pose(np.zeros(smplx.num_betas))[1], dtype=np.float64)
    rot, joints = vrm_tpose(rest, smplx.parents, smplx.skeleton_joint_names)
    idx = {n: j for j, n in enumerate(smplx.skeleton_joint_names)}
    for a, b, want in (
        ("left_index1", "left_index2", [1, 0, 0]),
        ("right_middle2", "right_middle3", [-1, 0, 0]),
        ("left_wrist", "left_middle1", [1, 0, 0]),
        ("left_thumb1", "left_thumb2", [2**-0.5, 0, 2**-0.5]),
        ("right_thumb2", "right_thumb3", [-(2**-0.5), 0, 2**-0.5]),
    ):
        d = joints[idx[b]] - joints[idx[a]]
        np.testing.assert_allclose(d / np.linalg.norm(d), want, atol=1e-6)
    np.testing.assert_allclose(np.einsum("jab,jcb->jac", rot, rot), np.broadcast_to(np.eye(3), rot.shape), atol=1e-12)
    # bones keep their lengths
    lengths = np.linalg.norm(rest[1:] - rest[smplx.parents[1:]], axis=1)
    np.testing.assert_allclose(np.linalg.norm(joints[1:] - joints[smplx.parents[1:]], axis=1), lengths, atol=1e-12)


class _Posed(GlbReader):
    """The .vrm with the .vrma's keyframe ``frame`` applied to its humanoid bones (plain FK retargeting:
    both files share the VRM T-pose with identity rest rotations)."""

    def __init__(self, vrm, vrma) -> None:
        super().__init__(vrm)
        self.clip = GlbReader(vrma)

    def node_trs(self, frame):
        trans = np.array([n.translation or [0.0, 0.0, 0.0] for n in self.gltf.nodes], dtype=np.float64)
        quat = np.array([n.rotation or [0.0, 0.0, 0.0, 1.0] for n in self.gltf.nodes], dtype=np.float64)
        ours = self.gltf.extensions["VRMC_vrm"]["humanoid"]["humanBones"]
        theirs = {
            b["node"]: name
            for name, b in self.clip.gltf.extensions["VRMC_vrm_animation"]["humanoid"]["humanBones"].items()
        }
        clip_trs = self.clip.node_trs(frame)
        anim = self.clip.gltf.animations[0]
        for ch in anim.channels:
            target = ours[theirs[ch.target.node]]["node"]
            if ch.target.path == "rotation":
                quat[target] = clip_trs[1][ch.target.node]
            else:
                trans[target] = clip_trs[0][ch.target.node]
        return trans, quat


def test_avatar_posed_by_the_clip_equals_the_model(open_files):
    model, motion, vrm, vrma, avatar, clip = open_files
    posed = _Posed(vrm, vrma)
    offset = np.array(posed.gltf.asset.extras["smplcore"]["offset_m"])
    plain = without_correctives(model)
    params = motion.model_params("open", model.skeleton_joint_names)
    ids = _written_vertices(posed, model)
    worst = 0.0
    for k in range(0, motion.num_frames, 3):
        out = plain(**{n: v[k : k + 1] if n != "betas" else v for n, v in params.items()})
        err = np.abs(posed.skinned_vertices(k) - (out.vertices[0][ids] + offset)).max()
        worst = max(worst, err)
        np.testing.assert_allclose(posed.joint_positions(k), out.joints[0, :24] + offset, atol=2e-5)
    assert worst < 1e-5, f"vertices off by {worst * 1000:.4f} mm"  # float32 files and model
    assert clip.num_frames == motion.num_frames and clip.num_joints == 22
    assert avatar.top4_max_error == 0.0  # the open model has at most 4 weights per vertex


def test_smplx_avatar_posed_by_the_clip_equals_the_model(smplx_files):
    model, motion, vrm, vrma = smplx_files
    posed = _Posed(vrm, vrma)
    offset = np.array(posed.gltf.asset.extras["smplcore"]["offset_m"])
    plain = without_correctives(model)
    params = motion.model_params("smplx", model.skeleton_joint_names)
    eyes = [i for i, n in enumerate(model.skeleton_joint_names) if "eye" in n]
    params["leye_pose"] = params["reye_pose"] = np.zeros_like(params["leye_pose"])  # VRM animates eyes by look-at
    ids = _written_vertices(posed, model)
    for k in (0, 7, motion.num_frames - 1):
        out = plain(**{n: v[k : k + 1] if n != "betas" else v for n, v in params.items()})
        err = np.abs(posed.skinned_vertices(k) - (out.vertices[0][ids] + offset)).max()
        assert err < 1e-5, f"frame {k}: {err * 1000:.4f} mm"
        np.testing.assert_allclose(posed.joint_positions(k), out.joints[0, :55] + offset, atol=1e-5)
    assert len(eyes) == 2


def _written_vertices(reader, model):
    prim = reader.gltf.meshes[0].primitives[0]
    written = reader.array(prim.indices).reshape(-1, 3)
    ids = np.full(reader.array(prim.attributes.POSITION).shape[0], -1)
    ids[written.ravel()] = np.asarray(model.faces).ravel()
    return ids


def test_textured_avatar(tmp_path):
    model = open_model()
    report = save_vrm(tmp_path / "t.vrm", model, texture="uv-grid")
    gltf = GlbReader(tmp_path / "t.vrm").gltf
    assert gltf.images[0].mimeType == "image/png"
    assert gltf.materials[0].pbrMetallicRoughness.baseColorTexture.index == 0
    assert gltf.meshes[0].primitives[0].attributes.TEXCOORD_0 is not None
    result = validate(tmp_path / "t.vrm")
    assert result["issues"]["numErrors"] == 0 and result["issues"]["numWarnings"] == 0, issues(result, 1)
    assert report.num_vertices == 14517  # split along the UV seams
    with pytest.raises(ValueError, match="texture: a texture needs the model's UV map"):
        save_vrm(tmp_path / "u.vrm", model, texture="uv-grid", uv=False)


def test_dropped_rotations_are_reported(tmp_path):
    model = open_model()
    motion = make_motion("smpl", seconds=0.5)
    with pytest.warns(UserWarning, match=r"no bone for left_hand \(up to [0-9.]+ deg\), right_hand"):
        report = save_vrma(tmp_path / "m.vrma", model, motion)
    assert any("left_hand" in w for w in report.warnings)
    with pytest.raises(ValueError, match="expected a .vrma file"):
        save_vrma(tmp_path / "m.glb", model, motion)


# --------------------------------------------------------------------------------------------------
# three-vrm in headless Chromium

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMIUM_ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--disable-gpu-sandbox"]
PAGE = """<!doctype html><html><head><link rel="icon" href="data:,"></head><body style="margin:0;background:#fff">
<script type="importmap">{"imports": {
  "three": "./node_modules/three/build/three.module.js",
  "three/addons/": "./node_modules/three/examples/jsm/",
  "@pixiv/three-vrm": "./node_modules/@pixiv/three-vrm/lib/three-vrm.module.js",
  "@pixiv/three-vrm-animation": "./node_modules/@pixiv/three-vrm-animation/lib/three-vrm-animation.module.js"}}
</script>
<script type="module">
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { VRMLoaderPlugin } from "@pixiv/three-vrm";
import { VRMAnimationLoaderPlugin, createVRMAnimationClip } from "@pixiv/three-vrm-animation";
try {
  const loader = new GLTFLoader();
  loader.register((p) => new VRMLoaderPlugin(p));
  loader.register((p) => new VRMAnimationLoaderPlugin(p));
  const vrm = (await loader.loadAsync("avatar.vrm")).userData.vrm;
  const vrma = (await loader.loadAsync("clip.vrma")).userData.vrmAnimations[0];
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0xffffff);
  scene.add(vrm.scene, new THREE.HemisphereLight(0xffffff, 0x888888, 2.0));
  const sun = new THREE.DirectionalLight(0xffffff, 2.0);
  sun.position.set(1, 2, 3);
  scene.add(sun);
  const mixer = new THREE.AnimationMixer(vrm.scene);
  mixer.clipAction(createVRMAnimationClip(vrma, vrm)).play();
  mixer.setTime(FRAME / FPS);
  vrm.update(0);
  vrm.scene.updateMatrixWorld(true);
  const camera = new THREE.PerspectiveCamera(30, 480 / 640, 0.1, 20);
  camera.position.set(0.5, 0.9, 5.2);
  camera.lookAt(0.5, 0.85, 0.2);
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setSize(480, 640);
  document.body.appendChild(renderer.domElement);
  renderer.render(scene, camera);
  await new Promise((done) => requestAnimationFrame(() => { renderer.render(scene, camera); done(); }));
  const bones = {};
  for (const name of Object.keys(vrm.humanoid.humanBones)) {
    const node = vrm.humanoid.getRawBoneNode(name);
    if (node) bones[name] = node.getWorldPosition(new THREE.Vector3()).toArray();
  }
  window.result = { bones, metaVersion: vrm.meta.metaVersion, name: vrm.meta.name, licenseUrl: vrm.meta.licenseUrl,
                    duration: vrma.duration };
} catch (e) { window.result = { error: String(e && e.stack || e) }; }
</script></body></html>"""


@pytest.fixture(scope="module")
def browser():
    if CHROMIUM is None:
        pytest.skip("Chromium is not installed (Debian: apt-get install chromium; .ci/run installs it)")
    sync_api = pytest.importorskip("playwright.sync_api", reason="Playwright is missing: pip install playwright")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


def three_vrm_pose(browser, folder, vrm, vrma, frame: int, fps: float):
    """three-vrm loading ``vrm`` and playing ``vrma`` at ``frame`` in Chromium: (result dict, screenshot
    (H, W, 3) uint8, console messages)."""
    from PIL import Image

    _, modules = node_package("@pixiv/three-vrm-animation")
    node_package("@pixiv/three-vrm")
    site = folder / "site"
    site.mkdir(exist_ok=True)
    (site / "node_modules").symlink_to(modules, target_is_directory=True)
    shutil.copy(vrm, site / "avatar.vrm")
    shutil.copy(vrma, site / "clip.vrma")
    (site / "index.html").write_text(PAGE.replace("FRAME", str(frame)).replace("FPS", repr(float(fps))))
    handler = functools.partial(_QuietHandler, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        page = browser.new_page(viewport={"width": 480, "height": 640})
        console: list[str] = []
        page.on("console", lambda m: console.append(f"{m.type}: {m.text}"))
        page.on("pageerror", lambda e: console.append(f"pageerror: {e}"))
        page.goto(f"http://127.0.0.1:{server.server_address[1]}/index.html")
        page.wait_for_function("window.result !== undefined", timeout=120_000)
        result = page.evaluate("window.result")
        shot = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB"))
        page.close()
    finally:
        server.shutdown()
        server.server_close()
    return result, shot, console


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    extensions_map = {**http.server.SimpleHTTPRequestHandler.extensions_map, ".js": "text/javascript"}

    def log_message(self, *args):  # no request log on stderr
        pass


def body_pixels(img: np.ndarray) -> float:
    """Share of the picture that is not the white background: the lit body."""
    return float((img.astype(int).min(axis=-1) < 235).mean())


def test_three_vrm_retargets_smplx_fingers_in_chromium(smplx_files, browser, tmp_path):
    """SMPL-X: three-vrm resolves all 55 bones; three-vrm-animation turns the clip's rotations into the
    avatar's normalised bones through the rest rotations and back: joints equal the model's."""
    model, motion, vrm, vrma = smplx_files
    frame = 9
    result, _, console = three_vrm_pose(browser, tmp_path, vrm, vrma, frame, motion.fps)
    assert "error" not in result, result.get("error")
    assert len(result["bones"]) == 55 and "rightLittleDistal" in result["bones"]
    assert not [m for m in console if m.startswith(("error", "pageerror", "warning"))], console
    offset = np.array(GlbReader(vrm).gltf.asset.extras["smplcore"]["offset_m"])
    params = motion.model_params("smplx", model.skeleton_joint_names)
    params["leye_pose"] = params["reye_pose"] = np.zeros_like(params["leye_pose"])
    out = model(**{n: v[frame : frame + 1] if n != "betas" else v for n, v in params.items()})
    joints = out.joints[0] + offset
    by_bone = {HUMAN_BONES[n]: joints[j] for j, n in enumerate(model.skeleton_joint_names)}
    for bone, where in result["bones"].items():
        np.testing.assert_allclose(where, by_bone[bone], atol=1e-4, err_msg=bone)


def test_three_vrm_poses_the_avatar_in_chromium(open_files, browser, tmp_path):
    model, motion, vrm, vrma, _, _ = open_files
    frame = 20
    result, shot, console = three_vrm_pose(browser, tmp_path, vrm, vrma, frame, motion.fps)
    assert "error" not in result, result.get("error")
    assert sorted(result["bones"]) == OPEN_BONES  # three-vrm resolved every humanoid bone
    assert result["metaVersion"] == "1" and result["licenseUrl"] == "https://vrm.dev/licenses/1.0/"
    assert abs(result["duration"] - (motion.num_frames - 1) / motion.fps) < 1e-6
    assert not [m for m in console if m.startswith(("error", "pageerror", "warning"))], console
    # three-vrm's posed skeleton is the model's, joint by joint
    offset = np.array(GlbReader(vrm).gltf.asset.extras["smplcore"]["offset_m"])
    params = motion.model_params("open", model.skeleton_joint_names)
    joints = model(**{n: v[frame : frame + 1] if n != "betas" else v for n, v in params.items()}).joints[0] + offset
    names = list(model.skeleton_joint_names)
    by_bone = {HUMAN_BONES[n]: joints[j] for j, n in enumerate(names) if n in HUMAN_BONES}
    for bone, where in result["bones"].items():
        np.testing.assert_allclose(where, by_bone[bone], atol=1e-4, err_msg=bone)
    from PIL import Image

    Image.fromarray(shot).save(tmp_path / "three_vrm.png")
    assert body_pixels(shot) > 0.03, f"no body in the screenshot {tmp_path / 'three_vrm.png'}"


def test_cli_writes_vrm_vrma_and_engine_glb(tmp_path, capsys, fake_models):
    from smplcore.cli import main
    from smplcore.motion import save_motion

    motion = make_motion("smplh", seconds=0.5, fps=30.0, num_betas=16)
    save_motion(motion, tmp_path / "walk.npz")
    model = ["--model-path", str(fake_models["smplh_female_npz"])]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["export", str(tmp_path / "walk.npz"), "-o", str(tmp_path / "a.vrm"), *model]) == 0
        assert main(["export", str(tmp_path / "walk.npz"), "-o", str(tmp_path / "a.vrma"), *model]) == 0
        assert main(["export", str(tmp_path / "walk.npz"), "-o", str(tmp_path / "u.glb"), "--engine", "unreal"]) == 0
    out = capsys.readouterr().out
    assert f"wrote {tmp_path / 'a.vrm'} (vrm" in out and "the rest pose, 52 joints" in out
    assert "engine: unreal (root bone 'root', lengths x100" in out
    bones = GlbReader(tmp_path / "a.vrm").gltf.extensions["VRMC_vrm"]["humanoid"]["humanBones"]
    assert len(bones) == 52 and "leftLittleDistal" in bones  # SMPL+H: body and 30 finger bones
    assert (
        GlbReader(tmp_path / "a.vrm")
        .gltf.extensions["VRMC_vrm"]["meta"]["otherLicenseUrl"]
        .startswith("https://mano.is.tue.mpg.de")
    )
    clip = GlbReader(tmp_path / "a.vrma")
    assert len(clip.gltf.animations[0].channels) == 52 + 1  # every joint a bone, plus the hips translation
    for name in ("a.vrm", "a.vrma", "u.glb"):
        report = validate(tmp_path / name)
        assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, issues(report, 1)
    assert main(["export", str(tmp_path / "walk.npz"), "-o", str(tmp_path / "c"), "--format", "vrma"]) == 0
    assert (tmp_path / "c.vrma").is_file()  # OUT without a suffix gets the format's
    assert main(["export", str(tmp_path / "walk.npz"), "-o", str(tmp_path / "c.glb"), "--format", "vrm"]) != 0
    assert "--format vrm" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "walk.npz"), "-o", str(tmp_path / "b.vrm"), "--engine", "unity"]) != 0
    assert "--engine/--unit-scale: engine conventions apply to .glb files, not '.vrm'" in capsys.readouterr().err


def test_the_clip_plays_on_another_avatar(open_files, smplx_files, browser, tmp_path):
    """The open model's clip on the SMPL-X avatar (another skeleton and body): three-vrm-animation retargets it
    through both T-poses, so the arm bones (straight along X in both rest poses) point where the open model's do."""
    model, motion, _, vrma, _, _ = open_files
    _, _, other_vrm, _ = smplx_files
    frame = 12
    result, shot, console = three_vrm_pose(browser, tmp_path, other_vrm, vrma, frame, motion.fps)
    assert "error" not in result, result.get("error")
    assert not [m for m in console if m.startswith(("error", "pageerror", "warning"))], console
    params = motion.model_params("open", model.skeleton_joint_names)
    joints = model(**{n: v[frame : frame + 1] if n != "betas" else v for n, v in params.items()}).joints[0]
    at = {HUMAN_BONES[n]: joints[j] for j, n in enumerate(model.skeleton_joint_names) if n in HUMAN_BONES}
    bones = {k: np.asarray(v) for k, v in result["bones"].items()}
    for side in ("left", "right"):
        for a, b in (("UpperArm", "LowerArm"), ("LowerArm", "Hand")):
            want = at[side + b] - at[side + a]
            got = bones[side + b] - bones[side + a]
            cosine = float(want @ got / np.linalg.norm(want) / np.linalg.norm(got))
            assert cosine > 1 - 1e-6, f"{side}{a}: {np.degrees(np.arccos(min(cosine, 1.0))):.3f} deg apart"
    assert body_pixels(shot) > 0.01
