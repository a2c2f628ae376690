"""The Pipeline from Python: a scene from numpy arrays, frames, the mask
against the ray-cast reference, outputs that stay valid, errors, the GIL."""

import sys
import threading

import numpy as np
import pytest

import shadowcull as sc
from conftest import cube_arrays, quad_arrays, translation

CAMERA = sc.look_at(eye=(6.0, 5.0, 8.0), target=(0.0, 0.0, 0.0), fov_y_deg=57.3)


def box_scene(**options):
    """A ground quad, three cubes, a point light and a sun."""
    p = sc.Pipeline(**options)
    ground = p.add_mesh(*quad_arrays())
    cube = p.add_mesh(*cube_arrays())
    p.add_object(ground)
    cubes = [p.add_object(cube, translation(x, 0.0, z)) for x, z in [(0, 0), (-3, 1), (2, -3)]]
    lamp = p.add_light("point", position=(2.0, 8.0, 1.0))
    sun = p.add_light("sun", elevation_deg=40.0, azimuth_deg=30.0)
    return p, cubes, lamp, sun


@pytest.mark.parametrize("stencil", ["bf", "db", "h", "auto"])
@pytest.mark.parametrize("culling", ["none", "chcpp", "auto"])
def test_mask_equals_the_reference(stencil, culling):
    p, cubes, lamp, sun = box_scene(stencil=stencil, culling=culling)
    for frame in range(3):
        f = p.frame(320, 240, camera=CAMERA)
        assert f.number == frame
        for light in (lamp, sun):
            mask = f.mask[light]
            assert mask.shape == (240, 320) and mask.dtype == np.uint8
            classes = np.bincount(mask.ravel(), minlength=4)
            assert classes[sc.SHADOW] > 100, "the cubes cast shadows on the ground"
            assert classes[sc.LIT] > 100
            ref = p.reference_mask(light)
            assert ref.mask.shape == mask.shape
            assert ref.mismatches(mask) == 0
        # A culled frame equals the unculled one: PSR holds every visible object.
        assert set(f.psr.tolist()) <= {0, *(c.bits for c in cubes)}
        p.set_transform(cubes[0], translation(0.2 * (frame + 1), 0.0, 0.0))


def test_culled_masks_equal_unculled():
    culled, _, lamp, sun = box_scene(stencil="h", culling="chcpp")
    plain, _, _, _ = box_scene(stencil="bf", culling="none")
    a = culled.frame(256, 192, camera=CAMERA)
    b = plain.frame(256, 192, camera=CAMERA)
    for light in (lamp, sun):
        np.testing.assert_array_equal(a.mask[light], b.mask[light])
    assert a.stats["eye_queries"] > 0 and b.stats["eye_queries"] == 0


def test_volumes_are_drawable():
    p, cubes, lamp, sun = box_scene(stencil="none", culling="chcpp")
    f = p.frame(320, 240, camera=CAMERA)
    assert f.mask[lamp] is None
    for light in (lamp, sun):
        v = f.volumes[light]
        assert v.positions.dtype == np.float32 and v.positions.shape[1] == 4
        assert v.indices.dtype == np.uint32 and len(v.indices) % 3 == 0
        assert v.ranges.dtype == sc.RANGE_DTYPE
        assert set(v.ranges["object"].tolist()) <= set(f.psc[light].tolist())
        assert set(v.ranges["object"].tolist()) >= {c.bits for c in cubes}
        for r in v.ranges:
            idx = v.indices[r["first_index"]: r["first_index"] + r["index_count"]]
            assert len(idx) == r["index_count"] > 0
            assert idx.min() >= r["first_vertex"]
            assert idx.max() < r["first_vertex"] + r["vertex_count"]
            assert r["method"] in (sc.ZPASS, sc.ZFAIL, sc.ZPPLUS)
            np.testing.assert_array_equal(r["world_from_local"], p.transform(sc.ObjectId.from_bits(r["object"])))
        # The directional light has no dark caps; w = 0 marks vertices at infinity.
        if light == sun:
            assert (v.ranges["dark_cap"][:, 0] == v.ranges["dark_cap"][:, 1]).all()
        assert set(np.unique(v.positions[:, 3]).tolist()) <= {0.0, 1.0}
        assert f.light_stats[light]["volume_triangles"] == len(v.indices) // 3


def test_strided_and_float64_positions_give_the_same_mesh():
    corners, tris = cube_arrays()
    wide = np.zeros((8, 6), np.float64)
    wide[:, ::2] = corners  # a strided float64 view: every other column
    strided = wide[:, ::2]
    assert not strided.flags["C_CONTIGUOUS"]
    results = []
    for positions, indices in [(corners, tris), (strided, tris.ravel().astype(np.int32))]:
        p = sc.Pipeline(stencil="bf", culling="none")
        p.add_object(p.add_mesh(*quad_arrays()))
        p.add_object(p.add_mesh(positions, indices), translation(0, 0.5, 0))
        light = p.add_light("point", position=(2.0, 8.0, 1.0))
        results.append(p.frame(200, 150, camera=CAMERA).mask[light])
    np.testing.assert_array_equal(results[0], results[1])
    assert np.count_nonzero(results[0] == sc.SHADOW) > 0


def test_outputs_are_copies_that_stay_valid():
    p, cubes, lamp, _ = box_scene(stencil="h", culling="chcpp")
    first = p.frame(256, 192, camera=CAMERA)
    kept = (first.mask[lamp].copy(), first.psr.copy(), first.volumes[lamp].positions.copy())
    p.set_transform(cubes[0], translation(1.5, 0.0, 1.0))
    second = p.frame(256, 192, camera=CAMERA)
    assert not np.array_equal(second.mask[lamp], kept[0]), "the moved cube changes the mask"
    np.testing.assert_array_equal(first.mask[lamp], kept[0])
    np.testing.assert_array_equal(first.psr, kept[1])
    np.testing.assert_array_equal(first.volumes[lamp].positions, kept[2])


def test_view_projection_matrices_equal_look_at():
    eye, target = np.array([6.0, 5.0, 8.0]), np.zeros(3)
    f = (target - eye) / np.linalg.norm(target - eye)
    s = np.cross(f, [0.0, 1.0, 0.0])
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = s, u, -f
    view[:3, 3] = -view[:3, :3] @ eye
    fov, aspect, near, far = np.radians(50.0), 4.0 / 3.0, 0.1, 100.0
    t = 1.0 / np.tan(fov / 2)
    proj = np.zeros((4, 4))
    proj[0, 0], proj[1, 1] = t / aspect, t
    proj[2, 2], proj[2, 3] = -(far + near) / (far - near), -2 * far * near / (far - near)
    proj[3, 2] = -1.0
    a, _, lamp, _ = box_scene(stencil="bf")
    b, _, _, _ = box_scene(stencil="bf")
    fa = a.frame(320, 240, view=view, projection=proj)
    fb = b.frame(320, 240, camera=sc.look_at(eye, target, fov_y_deg=50.0, near=0.1))
    np.testing.assert_array_equal(fa.psr, fb.psr)
    assert a.reference_mask(lamp).mismatches(fa.mask[lamp]) == 0
    # The same mask up to pixels on the rounding edge of a shadow.
    assert np.count_nonzero(fa.mask[lamp] != fb.mask[lamp]) < 20
    # The host's near plane catches a projection read with the wrong depth convention.
    a.frame(320, 240, view=view, projection=proj, near=near)
    with pytest.raises(ValueError, match="near.*is NegativeOneToOne, not ZeroToOne"):
        a.frame(320, 240, view=view, projection=proj, clip_depth="zero_to_one", near=near)
    # A projection made for another viewport's aspect, unless the pixels are not square.
    with pytest.raises(ValueError, match="viewport.*aspect"):
        a.frame(400, 240, view=view, projection=proj)
    a.frame(400, 240, view=view, projection=proj, anamorphic=True)


def test_edits_between_frames():
    p, cubes, lamp, sun = box_scene(stencil="h", culling="chcpp")
    p.frame(160, 120, camera=CAMERA)
    p.remove_object(cubes[1])
    p.set_flags(cubes[2], casts=False)
    p.set_light(lamp, "spot", position=(0.0, 6.0, 0.0), direction=(0.0, -1.0, 0.0), apex_deg=60.0)
    f = p.frame(160, 120, camera=CAMERA)
    assert cubes[1].bits not in f.psr.tolist()
    assert cubes[2].bits not in f.psc[sun].tolist()
    assert "Spot" in p.light(lamp)
    for light in (lamp, sun):
        assert p.reference_mask(light).mismatches(f.mask[light]) == 0
    p.remove_light(sun)
    assert p.lights == [lamp]
    with pytest.raises(ValueError, match="edited after the last frame"):
        p.reference_mask(lamp)  # the last frame no longer describes the lights
    with pytest.raises(ValueError, match="object"):
        p.set_transform(cubes[1], np.eye(4))  # a removed object's id is stale


def test_a_lod_change_keeps_the_id_and_the_mask_exact():
    p, cubes, lamp, sun = box_scene(stencil="h", culling="chcpp")
    before = p.frame(160, 120, camera=CAMERA)
    pos, idx = cube_arrays()
    tall = p.add_mesh(np.asarray(pos) * [1.0, 3.0, 1.0], idx, name="tall")
    p.set_mesh(cubes[0], tall)
    f = p.frame(160, 120, camera=CAMERA)
    assert cubes[0].bits in f.psr.tolist()
    assert not np.array_equal(f.mask[lamp], before.mask[lamp]), "the taller cube casts farther"
    for light in (lamp, sun):
        assert p.reference_mask(light).mismatches(f.mask[light]) == 0
    with pytest.raises(TypeError, match="mesh"):
        p.set_mesh(cubes[0], cubes[1])  # type: ignore[arg-type]


def test_objects_and_lights_added_into_reserved_room():
    p, cubes, lamp, sun = box_scene(stencil="h", culling="chcpp")
    p.reserve(16, 4)
    p.frame(160, 120, camera=CAMERA)
    cube = p.add_mesh(*cube_arrays())
    more = [p.add_object(cube, translation(-1.5 * k, 0.0, 3.0)) for k in range(4)]
    spot = p.add_light("spot", position=(0.0, 6.0, 2.0), direction=(0.0, -1.0, 0.0), apex_deg=70.0)
    f = p.frame(160, 120, camera=CAMERA)
    assert {c.bits for c in more} & set(f.psr.tolist()), "the added cubes are seen"
    for light in (lamp, sun, spot):
        assert p.reference_mask(light).mismatches(f.mask[light]) == 0
    with pytest.raises(ValueError, match="objects"):
        p.reserve(-1, 0)


def test_a_host_occluder_inside_its_object_keeps_the_mask_exact():
    p, cubes, lamp, sun = box_scene(stencil="bf", culling="chcpp", occluders="proxy")
    pos, idx = cube_arrays()
    inner = p.add_mesh(0.25 + 0.5 * np.asarray(pos), idx, name="inner")
    for c in cubes:
        p.set_occluder(c, inner)
    for frame in range(3):
        f = p.frame(320, 240, camera=CAMERA)
        for light in (lamp, sun):
            assert p.reference_mask(light).mismatches(f.mask[light]) == 0
    outer = p.add_mesh(2.0 * np.asarray(pos) - 0.5, idx, name="outer")
    with pytest.raises(ValueError, match="reach outside"):
        p.set_occluder(cubes[0], outer)
    p.set_occluder(cubes[0])  # back to its own mesh
    p.frame(320, 240, camera=CAMERA)


def test_a_host_depth_stands_in_for_the_eye_pass():
    p, cubes, lamp, sun = box_scene(stencil="bf", culling="chcpp")
    # Nothing drawn: nothing hidden, the masks exact.
    f = p.frame(320, 240, camera=CAMERA, host_depth=np.zeros((240, 320), np.float32))
    assert {c.bits for c in cubes} <= set(f.psr.tolist())
    for light in (lamp, sun):
        assert p.reference_mask(light).mismatches(f.mask[light]) == 0
    # A wall at the near plane hides everything, once each object is queried again.
    for _ in range(12):
        f = p.frame(320, 240, camera=CAMERA, host_depth=np.ones((240, 320)))
    assert f.psr.size == 0
    with pytest.raises(ValueError, match="host_depth.*culling size"):
        p.frame(320, 240, camera=CAMERA, host_depth=np.zeros((120, 160)))
    with pytest.raises(ValueError, match="host_depth"):
        p.frame(320, 240, camera=CAMERA, host_depth=np.zeros(10))


def test_reset_history_equals_a_fresh_pipeline():
    def path_frame(p, i):
        return p.frame(200, 150, camera=sc.look_at((6.0 - 0.3 * i, 5.0, 8.0), (0, 0, 0)))

    a, _, lamp, sun = box_scene(stencil="h", culling="chcpp")
    for i in range(3):
        path_frame(a, i)
    a.reset_history()
    a.set_frame_number(3)
    fresh, _, _, _ = box_scene(stencil="h", culling="chcpp")
    fresh.set_frame_number(3)
    fa, fb = path_frame(a, 3), path_frame(fresh, 3)
    assert fa.number == fb.number == 3
    np.testing.assert_array_equal(fa.psr, fb.psr)
    for light in (lamp, sun):
        np.testing.assert_array_equal(fa.psc[light], fb.psc[light])
        np.testing.assert_array_equal(fa.mask[light], fb.mask[light])
        assert fa.light_stats[light]["queries"] == fb.light_stats[light]["queries"]
    assert fa.stats["eye_queries"] == fb.stats["eye_queries"]


def test_options_by_name():
    p = sc.Pipeline(culling="chcpp", chcpp={"batch": 20}, tile=16)
    o = p.options
    assert (o["culling"], o["chcpp"]["batch"], o["tile"]) == ("chcpp", 20, 16)
    assert set(o) == set(sc.default_options())
    p.set_options(stencil="h")
    assert (p.options["stencil"], p.options["tile"]) == ("h", 16)


def test_the_gpu_host_preset():
    g = sc.gpu_host_options()
    assert (g["stencil"], g["culling"], g["scissor"], g["reference_every"]) == ("none", "auto", True, 0)
    assert (g["occluders"], sc.default_options()["occluders"]) == ("proxy", "mesh")
    assert (g["culling_resolution"], sc.default_options()["culling_resolution"]) == ([1920, 1080], None)
    coarse = sc.Pipeline(preset="gpu_host", culling_resolution=(320, 180))
    assert coarse.options["culling_resolution"] == [320, 180]
    assert set(g) == set(sc.default_options())
    assert sc.Pipeline(preset="gpu_host").options == g
    p = sc.Pipeline(preset="gpu_host", culling="chcpp", occluders="mesh")
    assert (p.options["culling"], p.options["stencil"], p.options["occluders"]) == ("chcpp", "none", "mesh")
    p.set_options(tile=16)
    assert (p.options["culling"], p.options["tile"]) == ("chcpp", 16)
    p.set_options(preset="batch", tile=4)
    assert p.options == dict(sc.default_options(), tile=4)


def _projective(call):
    """``call(pipeline, cube mesh, matrix)`` with a matrix whose bottom row is not (0, 0, 0, 1)."""
    p = sc.Pipeline()
    m = np.eye(4)
    m[3, 0] = 0.05
    call(p, p.add_mesh(*cube_arrays()), m)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: sc.Pipeline(cullng="chc"), "no such keyword `cullng`, expected one of"),
        (lambda: sc.Pipeline(stencil=None), r"options: `stencil`: got None"),
        (lambda: sc.Pipeline(threads=-1), r"options: `threads`: got -1, expected an integer from 0"),
        (lambda: sc.Pipeline(culling="sometimes"), r"`culling`: no such choice `sometimes`, expected one of `none`"),
        (lambda: sc.Pipeline().frame(64, 64, camera=sc.look_at((float("nan"), 1, 1), (0, 0, 0))), r"camera: eye\[0\] is NaN"),
        (lambda: sc.Pipeline().frame(-64, 64, camera=CAMERA), r"width: -64 is out of range"),
        (lambda: sc.Pipeline(preset="gpu"), "gpu_host"),
        (lambda: sc.Pipeline(tile=5), "tile"),
        (lambda: sc.Pipeline(culling="sometimes"), "sometimes"),
        (lambda: sc.Pipeline().add_mesh(np.zeros((4, 2), np.float32), [[0, 1, 2]]), r"\(n, 3\)"),
        (lambda: sc.Pipeline().add_mesh(np.zeros((4, 3), np.int32), np.array([[0, 1, 2]])), "float32 or float64"),
        (lambda: sc.Pipeline().add_mesh(np.zeros((4, 3), np.float32), np.array([[0, 1, 9]])), "9"),
        (lambda: sc.Pipeline().add_mesh(np.zeros((4, 3), np.float32), np.array([[0, -1, 2]])), "-1"),
        (lambda: sc.Pipeline().add_mesh(np.full((3, 3), np.nan, np.float32), np.array([0, 1, 2])), "finite"),
        (lambda: sc.Pipeline().add_object(sc.MeshId.from_bits(7)), "mesh 7: out of range"),
        (lambda: sc.ObjectId.from_bits(-1), r"ObjectId: -1 is out of range"),
        (lambda: _projective(lambda p, m, t: p.add_object(m, t)), r"being added.*projective"),
        (lambda: _projective(lambda p, m, t: p.set_transform(p.add_object(m), t)), r"object 0: transform is projective"),
        (lambda: sc.Pipeline().add_light("laser"), "unknown kind"),
        (lambda: sc.Pipeline().add_light("point", position=(0, 1, 0), rnage=3.0), "rnage"),
        (lambda: sc.Pipeline().add_light("directional", (0.0, 0.0, 0.0)), "direction"),
        (lambda: box_scene()[0].reference_mask(box_scene()[2]), "no frame"),
        (lambda: sc.Pipeline().frame(64, 64), "camera"),
        (lambda: sc.Pipeline().frame(0, 64, camera=CAMERA), "viewport"),
        (lambda: sc.run_job(None, out="/tmp/x", shard=(2, 2)), "shard"),
        (lambda: sc.run_job(None, out="/tmp/x", frames=0), "frames: must be at least 1"),
        (lambda: sc.run_job(None, out="/tmp/x", max_memory="1M"), "max_memory"),
        (lambda: sc.Pipeline(max_memory="lots"), "not a size"),
        (lambda: box_scene(max_memory="1M")[0].frame(64, 64, camera=CAMERA), "max_memory"),
    ],
)
def test_bad_input_is_a_value_error(call, match):
    with pytest.raises(ValueError, match=match) as e:
        call()
    for words in ("invalid type", "invalid value", "at line", "JSON", "u32", "4294967295"):
        assert words not in str(e.value).replace("0 to 4294967295", ""), str(e.value)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: sc.Pipeline().frame(64, 64, camera=np.eye(4)), r"camera: a pose from look_at\(\)"),
        (lambda: sc.Pipeline().remove_object("3"), r"obj: an ObjectId, got str"),
        (lambda: sc.Pipeline().remove_object(3), r"obj: an ObjectId, got int"),
        (lambda: sc.Pipeline().set_occluder(sc.ObjectId.from_bits(0), 1.5), r"mesh: a MeshId, got float"),
        (lambda: sc.ObjectId.from_bits("3"), r"ObjectId: an integer, got str"),
        (lambda: sc.Pipeline(chcpp=object()), r"options: object is not a number"),
    ],
)
def test_wrong_types_are_type_errors(call, match):
    with pytest.raises(TypeError, match=match):
        call()


def test_a_second_thread_waits_for_the_frame():
    import threading
    import time

    p, cubes, lamp, sun = box_scene(stencil="h", culling="chcpp")
    p.frame(1280, 960, camera=CAMERA)
    took = []

    def framing():
        start = time.perf_counter()
        p.frame(1280, 960, camera=CAMERA)
        took.append(time.perf_counter() - start)

    t = threading.Thread(target=framing)
    t.start()
    time.sleep(0.002)
    # Called while the other thread's frame runs (the GIL released): it
    # waits for the frame, where the native object would refuse with
    # "Already borrowed".
    p.set_transform(cubes[0], translation(0.5, 0.0, 0.0))
    t.join()
    assert took, "the frame ran"
    assert cubes[0].bits in p.frame(320, 240, camera=CAMERA).psr.tolist()


def test_files_are_os_errors(tmp_path):
    with pytest.raises(OSError, match="missing.glb"):
        sc.Pipeline().load(tmp_path / "missing.glb")
    with pytest.raises(OSError, match="no_job.ron"):
        sc.run_job(tmp_path / "no_job.ron", out=tmp_path / "out")
    bad = tmp_path / "bad.ron"
    bad.write_text("(version: 1, scene: City(()), resolution: (64, 64), pipeline: (tile: 5))")
    with pytest.raises(ValueError, match="bad.ron"):
        sc.run_job(bad, out=tmp_path / "out")


def test_load_a_shared_scene(shared_data):
    p = sc.Pipeline(stencil="h", culling="chcpp")
    loaded = p.load(shared_data / "scenes" / "cornell_box_multifile")
    assert len(loaded.objects) == 8
    light = p.add_light("above_scene", 0.9)
    f = p.frame(160, 160, camera=sc.look_at((0.0, 1.0, 3.4), (0.0, 1.0, 0.0), fov_y_deg=45.0))
    assert len(f.psr) > 0
    assert p.reference_mask(light).mismatches(f.mask[light]) == 0


def test_the_gil_is_released_during_a_frame():
    """Python runs on another thread while a frame computes. With a switch
    interval of a minute no thread is made to hand the GIL over: the main
    thread gets it back from the worker only if the frame releases it, and
    then counts to its target before the worker can finish."""
    p, _, _, _ = box_scene(stencil="bf", culling="none", reference_every=0)
    p.frame(64, 48, camera=CAMERA)
    started = threading.Event()
    state = {"done": False}

    def work():
        started.set()
        p.frame(1600, 1200, camera=CAMERA)
        state["done"] = True

    target, turns = 200_000, 0
    old = sys.getswitchinterval()
    sys.setswitchinterval(60.0)
    try:
        t = threading.Thread(target=work)
        t.start()
        started.wait()
        while not state["done"] and turns < target:
            turns += 1
        finished_first = state["done"]
    finally:
        sys.setswitchinterval(old)
    t.join()
    assert not finished_first and turns == target, f"{turns} turns before the frame ended"


def test_the_readme_snippet_runs():
    """README's "From Python" snippet, less its batch job (a 20-frame run)."""
    from conftest import ROOT

    text = (ROOT / "README.md").read_text()
    start = text.index("```python\n", text.index("## From Python")) + len("```python\n")
    code = text[start: text.index("```", start)]
    lines = [line for line in code.splitlines() if not line.startswith("sc.run_job(")]
    assert len(lines) < len(code.splitlines()), "the snippet shows a batch job"
    scope = {}
    exec("\n".join(lines), scope)
    assert np.count_nonzero(scope["mask"] == sc.SHADOW) > 0


def test_memory_limits_and_stale_outputs():
    """A frame over `max_memory` is refused and drops the last frame's
    outputs (the edits are applied); the reference's share counts only for
    `reference_mask`, which a frame never computes."""
    # The estimate (src/memory.rs): about 67 MB of base, 90 B per pixel with
    # two lights, 48 more with the reference: 2000×2000 needs ~430 MB
    # without it and ~620 MB with it.
    p, cubes, lamp, _ = box_scene(stencil="bf", light_resolution=64, max_memory="500M")
    p.frame(320, 240, camera=CAMERA)
    with pytest.raises(ValueError, match="max_memory"):
        p.frame(4000, 4000, camera=CAMERA)
    with pytest.raises(ValueError, match="no frame has run yet"):
        p.reference_mask(lamp)
    f = p.frame(2000, 2000, camera=CAMERA)
    assert f.mask[lamp].shape == (2000, 2000)
    with pytest.raises(ValueError, match="reference_every"):
        p.reference_mask(lamp)


def test_lights_before_the_first_frame():
    p = sc.Pipeline()
    p.add_object(p.add_mesh(*quad_arrays()))
    p.add_object(p.add_mesh(*cube_arrays()), translation(0.0, 0.0, 0.0))
    # Above the scene before any frame: 1.5 × its height (1) over its floor.
    above = p.add_light("above_scene", 1.5)
    assert p.light(above)["Point"]["position"][1] == pytest.approx(1.5)
    with pytest.raises(ValueError, match="NaN"):
        p.add_light("point", position=(float("nan"), 1.0, 1.0))
    with pytest.raises(ValueError, match="clip_depth"):
        p.frame(64, 48, camera=CAMERA, clip_depth="sideways")


@pytest.mark.parametrize(
    "clamping,receivers",
    [
        ("continuous", "all"),
        ("continuous", "psr"),
        ("continuous", "fragment"),
        ("discrete", "all"),
        ("auto", "fragment"),
    ],
)
def test_clamping_keeps_the_mask_and_numbers_segments(clamping, receivers):
    plain, cubes, lamp, sun = box_scene(stencil="bf", culling="chcpp")
    clamped, _, _, _ = box_scene(
        stencil="bf",
        culling="chcpp",
        clamping=clamping,
        clamping_receivers=receivers,
        slices=12,
    )
    a = plain.frame(320, 240, camera=CAMERA)
    b = clamped.frame(320, 240, camera=CAMERA)
    for light in (lamp, sun):
        differ = int((a.mask[light] != b.mask[light]).sum())
        assert differ <= 320 * 240 // 10_000, f"{differ} pixels differ"
        assert clamped.reference_mask(light).mismatches(b.mask[light]) == 0
        r = b.volumes[light].ranges
        finite = np.isfinite(r["far_plane"]).all(axis=1)
        # Discrete clamping leaves a caster the light's plane cuts unclamped
        # (segment 0 without planes), and its last segment may extrude to
        # infinity (no far plane).
        clamped_ranges = r[(r["segment"] > 0) | finite]
        assert b.light_stats[light]["segments"] == len(clamped_ranges) > 0
        if clamping == "continuous":
            assert finite.all() and len(clamped_ranges) == len(r)
        c = clamped_ranges
        assert (np.isnan(c["near_plane"]).all(axis=1) == (c["segment"] == 0)).all()
        assert np.isnan(a.volumes[light].ranges["far_plane"]).all()
    # Fill accounting: an `h` pipeline with `count_fill` counts what the two
    # brute-force frames processed, without and with clamping.
    counted, _, _, _ = box_scene(
        stencil="h",
        culling="chcpp",
        clamping=clamping,
        clamping_receivers=receivers,
        slices=12,
        count_fill=True,
    )
    c = counted.frame(320, 240, camera=CAMERA)
    for light in (lamp, sun):
        s = c.light_stats[light]
        assert s["bf_fill_unclamped"] == a.light_stats[light]["pixels_processed"] > 0
        assert s["bf_fill_clamped"] == b.light_stats[light]["pixels_processed"] > 0



def test_python_habits(tmp_path):
    import struct
    import zlib

    with sc.Pipeline(stencil="bf", culling="chcpp") as p:
        ground = p.add_mesh(*[a.tolist() for a in quad_arrays()])  # sequences are arrays
        cube = p.add_mesh(*cube_arrays())
        p.add_object(ground)
        c = p.add_object(cube, translation(0.0, 1.0, 0.0))
        lamp = p.add_light("point", position=(2.0, 8.0, 1.0))
        assert repr(p) == "Pipeline(objects=2, lights=1, culling='chcpp', stencil='bf')"
        # Flags read back; setting one keeps the others.
        assert p.flags(c) == dict(casts=True, receives=True, occludes=True, visible=True)
        p.set_flags(c, receives=False)
        assert p.flags(c) == dict(casts=True, receives=False, occludes=True, visible=True)
        f = p.frame(160, 120, camera=CAMERA)
        img = sc.mask_to_image(f.mask[lamp])
        assert img.dtype == np.uint8 and img.shape == (120, 160)
        assert set(np.unique(img)) <= set(sc.MASK_GREYS.tolist())
        assert (img == sc.MASK_GREYS[sc.SHADOW]).sum() == (f.mask[lamp] == sc.SHADOW).sum() > 0
        f.save_mask(lamp, tmp_path / "mask.png")
        png = (tmp_path / "mask.png").read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        w, h = struct.unpack(">II", png[16:24])
        assert (w, h) == (160, 120)
        n = struct.unpack(">I", png[33:37])[0]
        raw = zlib.decompress(png[41 : 41 + n])
        rows = np.frombuffer(raw, np.uint8).reshape(120, 161)[:, 1:]
        np.testing.assert_array_equal(rows, img)
        with pytest.raises(ValueError, match="not in this frame"):
            f.save_mask(sc.LightId.from_bits(lamp.bits + 1), tmp_path / "x.png")
    assert repr(p) == "Pipeline(closed)"
    with pytest.raises(ValueError, match="closed"):
        p.frame(160, 120, camera=CAMERA)
    p.close()  # twice is fine
    assert "Frees the pipeline" in (sc.Pipeline.close.__doc__ or "")


def test_the_procedural_city_from_python():
    p = sc.Pipeline(stencil="bf", culling="chcpp")
    city = p.add_city(blocks_x=2, blocks_z=2, seed=7)
    assert len(city.objects) == len(city.names) > 50
    assert sum(1 for n in city.names if n) > 50, "objects keep their names"
    assert "street" in city.paths and {"light", "sun"} <= set(city.lights)
    sun = p.add_light("named", "sun")
    f = p.frame(160, 120, camera=p.path_camera("street", 0))
    assert p.reference_mask(sun).mismatches(f.mask[sun]) == 0
    with pytest.raises(ValueError, match="city: no such keyword `blokcs_x`"):
        p.add_city(blokcs_x=2)


def test_handles_are_typed_and_stale_ones_stay_dead():
    p, cubes, lamp, sun = box_scene(stencil="bf", culling="chcpp")
    mesh = p.add_mesh(*cube_arrays())
    # A mesh's id where an object's is expected is a TypeError, not another object.
    with pytest.raises(TypeError, match="obj: an ObjectId, got MeshId"):
        p.remove_object(mesh)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="light: a LightId, got ObjectId"):
        p.remove_light(cubes[0])  # type: ignore[arg-type]
    assert repr(cubes[1]) == "ObjectId(slot=2, generation=0)"
    assert cubes[1] == sc.ObjectId.from_bits(cubes[1].bits) and cubes[1] != mesh
    assert len({cubes[1], sc.ObjectId.from_bits(cubes[1].bits)}) == 1
    # A removed object's slot is reused at the next generation; the old
    # handle stays stale.
    p.remove_object(cubes[1])
    again = p.add_object(mesh, translation(-3.0, 0.0, 1.0))
    assert (again.slot, again.generation) == (cubes[1].slot, 1)
    with pytest.raises(ValueError, match=r"object 2: removed \(a stale id"):
        p.set_transform(cubes[1], np.eye(4))
    # Meshes and lights too.
    p.remove_light(sun)
    lamp2 = p.add_light("sun", elevation_deg=30.0, azimuth_deg=10.0)
    assert (lamp2.slot, lamp2.generation) == (sun.slot, 1)
    with pytest.raises(ValueError, match="stale"):
        p.light(sun)
    spare = p.add_mesh(*cube_arrays())
    p.remove_mesh(spare)
    reused = p.add_mesh(*cube_arrays())
    assert (reused.slot, reused.generation) == (spare.slot, spare.generation + 1)
    with pytest.raises(ValueError, match="mesh"):
        p.remove_mesh(spare)
    f = p.frame(320, 240, camera=CAMERA)
    assert again.bits in f.psr.tolist()
    assert set(f.psc) == {lamp, lamp2}
    for light in (lamp, lamp2):
        assert p.reference_mask(light).mismatches(f.mask[light]) == 0
