"""shadowcull from Python: CPU-side culling middleware for stencil shadow volumes.

A :class:`Pipeline` holds a scene (meshes from numpy arrays, objects,
lights, or files loaded with :meth:`Pipeline.load`) and computes, once per
:meth:`Pipeline.frame`, the potentially shadowed receivers (PSR), per light
the potential shadow casters (PSC) and the shadow volumes to draw, and, with
a CPU stencil backend, the exact four-class shadow mask::

    import numpy as np
    import shadowcull as sc

    p = sc.Pipeline(culling="chcpp", stencil="h")
    ground = p.add_mesh(np.array([[-9, 0, -9], [-9, 0, 9], [9, 0, 9], [9, 0, -9]], np.float32),
                        np.array([[0, 1, 2], [0, 2, 3]]))
    p.add_object(ground)
    sun = p.add_light("sun", elevation_deg=40, azimuth_deg=30)
    f = p.frame(640, 480, camera=sc.look_at(eye=(6, 5, 8), target=(0, 0, 0)))
    f.psr, f.psc[sun], f.volumes[sun].ranges, f.mask[sun], f.stats["frame_ms"]

Meshes, objects and lights are named by typed handles (:class:`MeshId`,
:class:`ObjectId`, :class:`LightId`) that cannot be mixed up: a mesh's id
given where an object's is expected is a ``TypeError``. A removed thing's
slot is reused at its next generation, so a kept old handle is a
``ValueError`` (stale), never another thing. Output arrays (``psr``, ``psc``,
``ranges["object"]``) hold ids as uint64 numbers, their :attr:`ObjectId.bits`.

Batch jobs (the RON files of ``shadowcull run``) run with :func:`run_job`,
split over machines with ``shard=(i, n)`` and put back together with
:func:`merge`; ``python -m shadowcull.distributed`` fans a job out over a Ray
cluster.

Conventions are the library's (DESIGN.md): right-handed world, +y up;
matrices are numpy 4×4 arrays applied to column vectors (``M @ [x, y, z, 1]``);
masks are ``(height, width)`` arrays, row 0 at the top, of the pixel classes
:data:`LIT`, :data:`SHADOW`, :data:`UNLIT` and :data:`BACKGROUND`.

Every array a frame returns is a copy the caller owns: it stays valid and
unchanged after later frames. A pipeline runs one call at a time: another
thread's call while a frame runs waits for it to return; the GIL is
released while a frame, a reference mask, a load, a job or a merge runs.

Errors are ``ValueError`` for bad values (an unknown option, a value out of
its range, a malformed array, a stale id, a frame over ``max_memory``),
``TypeError`` for a value of the wrong type (a string for an id, an array
for a ``look_at`` pose), ``OSError`` for files (unreadable scenes or jobs, a
busy output directory) and ``MemoryError`` when a buffer cannot be
allocated, with a message naming the keyword, file, object or field.
"""

from __future__ import annotations

import functools
import json
import math
import numbers
import os
import struct
import threading
import zlib
from typing import Any, Dict, Iterable, List, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from . import _native

__version__: str = _native.__version__

__all__ = [
    "Pipeline",
    "MeshId",
    "ObjectId",
    "LightId",
    "Frame",
    "Volumes",
    "ReferenceMask",
    "Loaded",
    "look_at",
    "run_job",
    "merge",
    "default_options",
    "gpu_host_options",
    "RANGE_DTYPE",
    "LIT",
    "SHADOW",
    "UNLIT",
    "BACKGROUND",
    "ZPASS",
    "ZFAIL",
    "ZPPLUS",
]

#: Pixel classes of a mask (``mask.pixels``' ``PixelClass`` in Rust).
LIT, SHADOW, UNLIT, BACKGROUND = 0, 1, 2, 3
#: Stencil methods of a volume range (``ranges["method"]``).
ZPASS, ZFAIL, ZPPLUS = 0, 1, 2

#: One shadow-volume range per caster and segment: the fields of Rust's
#: ``raster::VolumeRange``. ``first_index``/``index_count`` select the range's
#: triangles in ``Volumes.indices``; ``light_cap``/``dark_cap`` are ``[begin,
#: end)`` index ranges; ``scissor`` is ``[x0, y0, x1, y1)`` in pixels
#: (optional: pixels outside cannot change); ``band`` likewise, but not
#: optional: the range must be drawn only inside it (a caster's volume drawn
#: once per band of the eye slices its receivers occupy);
#: ``world_from_local`` places the range's local-space positions;
#: ``near_plane``/``far_plane`` are a clamped segment's bounding planes
#: ``(a, b, c, d)`` in world space (NaN where there is none: the near plane
#: of segment 0, both planes of an unclamped volume).
RANGE_DTYPE = np.dtype(
    [
        ("object", np.uint64),
        ("segment", np.uint32),
        ("method", np.uint8),
        ("first_vertex", np.uint32),
        ("vertex_count", np.uint32),
        ("first_index", np.uint32),
        ("index_count", np.uint32),
        ("light_cap", np.uint32, (2,)),
        ("dark_cap", np.uint32, (2,)),
        ("scissor", np.uint32, (4,)),
        ("band", np.uint32, (4,)),
        ("depth_near", np.float32),
        ("depth_far", np.float32),
        ("world_from_local", np.float64, (4, 4)),
        ("near_plane", np.float64, (4,)),
        ("far_plane", np.float64, (4,)),
    ]
)

# Light kinds: the RON job's light variants, spelled in snake case.
_LIGHT_VARIANTS = {
    "point": "Point",
    "spot": "Spot",
    "directional": "Directional",
    "sun": "Sun",
    "above_scene": "AboveScene",
    "named": "Named",
}
# The variants that hold one value, and the keyword that may name it.
_LIGHT_VALUE = {"directional": "direction", "above_scene": "factor", "named": "name"}


def _plain(value: Any) -> Any:
    """JSON fallback for numpy values (arrays, scalars)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (tuple, set)):
        return list(value)
    raise TypeError(f"{type(value).__name__} is not a number, string, list or dict")


def _non_finite(value: Any, path: str) -> Optional[str]:
    """The path of the first NaN or infinity within ``value``, if any."""
    if isinstance(value, dict):
        for k, v in value.items():
            found = _non_finite(v, f"{path}.{k}" if path else str(k))
            if found is not None:
                return found
    elif isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray) and value.ndim > 0):
        for i, v in enumerate(value):
            found = _non_finite(v, f"{path}[{i}]")
            if found is not None:
                return found
    elif isinstance(value, (float, np.floating)) and not math.isfinite(float(value)):
        return path or "the value"
    return None


def _json(what: str, value: Any) -> str:
    try:
        return json.dumps(value, default=_plain, allow_nan=False)
    except ValueError:
        where = _non_finite(value, "")
        raise ValueError(f"{what}: {where} is {'NaN' if where else 'NaN or infinity'}: "
                         "values must be finite") from None
    except TypeError as e:
        raise TypeError(f"{what}: {e}") from None


class _Id:
    """A generational handle: a slot and a generation in one number
    (:attr:`bits`, slot in the low 32 bits). Made by the pipeline; equal
    and hashable by kind and bits."""

    __slots__ = ("_bits",)

    def __init__(self, bits: int):
        self._bits = int(bits)

    @classmethod
    def from_bits(cls: Any, bits: Any) -> Any:
        """The handle whose :attr:`bits` are ``bits`` (an element of an output
        array); what it names is checked where it is used."""
        v = _index(cls.__name__, bits, 2**64)
        return cls(v)

    @property
    def bits(self) -> int:
        """The id as one number, as output arrays hold it."""
        return self._bits

    @property
    def slot(self) -> int:
        """The slot: the index the library keeps the thing at."""
        return self._bits & 0xFFFFFFFF

    @property
    def generation(self) -> int:
        """How many times the slot was reused before."""
        return self._bits >> 32

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and other._bits == self._bits  # type: ignore[attr-defined]

    def __hash__(self) -> int:
        return hash((type(self).__name__, self._bits))

    def __repr__(self) -> str:
        return f"{type(self).__name__}(slot={self.slot}, generation={self.generation})"


class MeshId(_Id):
    """A mesh's handle (:meth:`Pipeline.add_mesh`)."""

    __slots__ = ()


class ObjectId(_Id):
    """An object's handle (:meth:`Pipeline.add_object`, :meth:`Pipeline.load`)."""

    __slots__ = ()


class LightId(_Id):
    """A light's handle (:meth:`Pipeline.add_light`); :class:`Frame`'s
    per-light dictionaries are keyed by it."""

    __slots__ = ()


def _handle(kind: Any, name: str, value: Any) -> int:
    """The bits of handle ``value``, which must be a ``kind``: a
    ``TypeError`` naming ``name`` otherwise (an int, or another kind's id)."""
    if type(value) is not kind:
        article = "an" if kind.__name__[0] in "AEIOU" else "a"
        raise TypeError(f"{name}: {article} {kind.__name__}, got {type(value).__name__}")
    return int(value.bits)


def _index(name: str, value: Any, end: int = 2**32) -> int:
    """``value`` as a size or number the library takes (0 to ``end`` − 1,
    2³² − 1 by default): a ``TypeError`` for a non-integer, a ``ValueError``
    out of range."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name}: an integer, got {type(value).__name__}")
    v = int(value)
    if not 0 <= v < end:
        raise ValueError(f"{name}: {v} is out of range (0 to {end - 1})")
    return v


def _camera(camera: Any) -> str:
    """The JSON of a :func:`look_at` pose, or a ``TypeError`` naming what
    was given instead."""
    if not isinstance(camera, dict):
        raise TypeError(
            f"camera: a pose from look_at() (a dict), got {type(camera).__name__}; "
            "for 4×4 matrices pass view= and projection="
        )
    return _json("camera", camera)


def _one_call_at_a_time(cls: Any) -> Any:
    """Makes every public method of ``cls`` hold the instance's lock: a
    second thread calling into a pipeline while another thread's call (a
    frame, which releases the GIL) runs waits until it returns."""
    for name, f in list(vars(cls).items()):
        if name.startswith("_") or not callable(f):
            continue

        def locked(self: Any, *args: Any, __f: Any = f, **kwargs: Any) -> Any:
            with self._lock:
                return __f(self, *args, **kwargs)

        functools.update_wrapper(locked, f)
        setattr(cls, name, locked)
    return cls


def _matrix(name: str, m: Any) -> np.ndarray:
    a = np.asarray(m, dtype=np.float64)
    if a.shape != (4, 4):
        raise ValueError(f"{name}: shape {a.shape} is not (4, 4)")
    return a


def look_at(
    eye: Sequence[float],
    target: Sequence[float],
    up: Sequence[float] = (0.0, 1.0, 0.0),
    fov_y_deg: float = 60.0,
    near: float = 0.1,
) -> Dict[str, Any]:
    """A camera pose for :meth:`Pipeline.frame` (the RON job's ``LookAt``):
    the aspect comes from the frame's size."""
    return {
        "eye": [float(x) for x in eye],
        "target": [float(x) for x in target],
        "up": [float(x) for x in up],
        "fov_y_deg": float(fov_y_deg),
        "near": float(near),
    }


def default_options() -> Dict[str, Any]:
    """The default pipeline options: every keyword :class:`Pipeline` takes."""
    return json.loads(_native.default_options())


def gpu_host_options() -> Dict[str, Any]:
    """The options of the ``gpu_host`` preset (``PipelineOptions::gpu_host``):
    what a renderer that draws the shadow volumes on its own GPU starts from
    (no CPU stencil, no reference, ``culling="auto"``, scissor rectangles).
    ``Pipeline(preset="gpu_host", **overrides)`` starts from it too."""
    return json.loads(_native.preset_options("gpu_host"))


#: Grey levels of :func:`mask_to_image`, per pixel class: lit white, shadow
#: dark grey, unlit (facing away from the light) black, background mid grey.
MASK_GREYS = np.array([255, 64, 0, 160], np.uint8)


def mask_to_image(mask: Any) -> np.ndarray:
    """A shadow mask's pixel classes (``LIT``, ``SHADOW``, ``UNLIT``,
    ``BACKGROUND``: codes 0–3) as an ``(h, w)`` uint8 grey image
    (:data:`MASK_GREYS`), ready for any image writer: saved directly, the
    codes 0–3 look black."""
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask: an (h, w) array, got shape {m.shape}")
    if m.size and (m.min() < 0 or m.max() > BACKGROUND):
        raise ValueError(f"mask: pixel classes are 0 to {BACKGROUND}, got {m.min()} to {m.max()}")
    return MASK_GREYS[m.astype(np.intp)]


def save_png(path: "os.PathLike[str] | str", image: Any) -> None:
    """Writes an ``(h, w)`` uint8 grey image as an 8-bit greyscale PNG
    (the standard library's zlib: no image package needed)."""
    a = np.ascontiguousarray(image, dtype=np.uint8)
    if a.ndim != 2:
        raise ValueError(f"image: an (h, w) array, got shape {a.shape}")
    h, w = a.shape
    raw = b"".join(b"\x00" + a[y].tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
    png += chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)


class Volumes(NamedTuple):
    """One light's shadow volumes, ready to draw: ``positions`` ``(n, 4)``
    float32 homogeneous local-space vertices (``w`` is 0 at infinity),
    ``indices`` a flat uint32 triangle list, ``ranges`` one
    :data:`RANGE_DTYPE` record per caster and segment."""

    positions: np.ndarray
    indices: np.ndarray
    ranges: np.ndarray


class ReferenceMask(NamedTuple):
    """The exact ray-cast mask of one light: ``mask`` ``(h, w)`` uint8 pixel
    classes, ``ambiguous`` ``(h, w)`` bool (pixels a comparison skips)."""

    mask: np.ndarray
    ambiguous: np.ndarray

    def mismatches(self, mask: np.ndarray) -> int:
        """Pixels where ``mask`` differs from the reference among those the
        reference calls lit or shadow and not ambiguous (Rust's
        ``mask::compare``)."""
        mask = np.asarray(mask)
        if mask.shape != self.mask.shape:
            raise ValueError(f"mask: shape {mask.shape} is not the reference's {self.mask.shape}")
        compared = ((self.mask == LIT) | (self.mask == SHADOW)) & ~self.ambiguous
        return int(np.count_nonzero(compared & (mask != self.mask)))


class Loaded(NamedTuple):
    """What :meth:`Pipeline.load` or :meth:`Pipeline.add_city` added: the
    new objects' handles (:class:`ObjectId`) and, in the same order, their names in the file (the
    node's, or the loader's for a nameless one; may be empty), and the
    file's named cameras (``LookAt`` dicts), camera paths and lights (use
    them with :meth:`Pipeline.path_camera` and ``add_light("named", name)``)."""

    objects: List[ObjectId]
    cameras: Dict[str, Dict[str, Any]]
    paths: List[str]
    lights: List[str]
    warnings: List[str]
    names: List[str]


class Frame:
    """The results of one :meth:`Pipeline.frame`, keyed by light id where
    per light. Every array is a copy the caller owns.

    Attributes:
        number: the frame's job number.
        psr: uint64 ids (:attr:`ObjectId.bits`) of the potentially shadowed
            receivers, in slot order.
        psc: per light (keyed by :class:`LightId`), uint64 ids of the
            potential shadow casters.
        volumes: per light, the :class:`Volumes` to draw.
        mask: per light, the ``(h, w)`` uint8 shadow mask, or None without a
            CPU stencil (``stencil="none"``).
        stats: the frame's counters and stage times (Rust's ``FrameStats``).
        light_stats: per light, its counters and stage times (``ShadowStats``).
        volume_stats: per light, volume construction counters (``VolumeStats``).
        views: per light, the number of light views (cube faces, frusta) used.
    """

    def __init__(self, raw: Dict[str, Any]):
        self.psr: np.ndarray = raw["psr"]
        self.stats: Dict[str, Any] = json.loads(raw["stats"])
        self.number: int = self.stats["frame"]
        self.psc: Dict[LightId, np.ndarray] = {}
        self.volumes: Dict[LightId, Volumes] = {}
        self.mask: Dict[LightId, Optional[np.ndarray]] = {}
        self.light_stats: Dict[LightId, Dict[str, Any]] = {}
        self.volume_stats: Dict[LightId, Dict[str, Any]] = {}
        self.views: Dict[LightId, int] = {}
        for light in raw["lights"]:
            i = LightId(light["id"])
            self.psc[i] = light["psc"]
            cols = light["ranges"]
            ranges = np.zeros(len(cols["object"]), dtype=RANGE_DTYPE)
            for name in RANGE_DTYPE.names:
                ranges[name] = cols[name]
            self.volumes[i] = Volumes(light["positions"], light["indices"], ranges)
            self.mask[i] = light["mask"]
            self.light_stats[i] = json.loads(light["stats"])
            self.volume_stats[i] = json.loads(light["volume_stats"])
            self.views[i] = light["views"]

    def __repr__(self) -> str:
        return (
            f"Frame(number={self.number}, psr={len(self.psr)}, "
            f"psc={ {k: len(v) for k, v in self.psc.items()} }, "
            f"frame_ms={self.stats['frame_ms']:.2f})"
        )

    def save_mask(self, light: LightId, path: "os.PathLike[str] | str") -> None:
        """Writes light ``light``'s mask as a greyscale PNG
        (:func:`mask_to_image`); a ``ValueError`` without a CPU stencil
        (``stencil="none"``) or for a light the frame did not compute."""
        _handle(LightId, "light", light)
        if light not in self.mask:
            raise ValueError(f"{light!r}: not in this frame (its lights: {list(self.mask)})")
        m = self.mask[light]
        if m is None:
            raise ValueError(f"{light!r}: no mask (stencil=\"none\" computes none)")
        save_png(path, mask_to_image(m))


def _loaded(objects: Any, meta: str) -> Loaded:
    m = json.loads(meta)
    return Loaded(
        [ObjectId(o) for o in objects],
        m["cameras"],
        m["paths"],
        m["lights"],
        m["warnings"],
        m["names"],
    )


class _Closed:
    """What a closed :class:`Pipeline` holds in place of its native object."""

    def __getattr__(self, name: str) -> Any:
        raise ValueError("the pipeline is closed")


@_one_call_at_a_time
class Pipeline:
    """The shadow-volume culling pipeline.

    ``Pipeline(**options)`` takes the RON job's ``pipeline`` fields as
    keywords, with the same names and values: ``culling="chcpp"``,
    ``stencil="h"``, ``method="auto"``, ``tile=8``, ``coverage="point"``,
    ``chcpp=dict(batch=50, revisit=5, seed=1)``, ``reference_every=0``, ...
    (see :func:`default_options`). An unknown name is a ``ValueError``.
    ``preset="gpu_host"`` starts from :func:`gpu_host_options` instead of
    the defaults; the other keywords override it.

    One pipeline runs one call at a time: a thread that calls into it while
    another thread's call runs (a frame releases the GIL) waits for it.
    """

    def __init__(self, **options: Any):
        self._lock = threading.RLock()
        self._p: Any = _native.Pipeline(_json("options", options))

    def close(self) -> None:
        """Frees the pipeline's scene, caches and buffers now, not when the
        object is collected; any later call is a ``ValueError``. Closing
        twice is allowed. ``with Pipeline(...) as p:`` closes on leaving."""
        self._p = _Closed()

    def __enter__(self) -> "Pipeline":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        if isinstance(self._p, _Closed):
            return "Pipeline(closed)"
        o = self.options
        return (
            f"Pipeline(objects={self._p.object_count()}, lights={len(self._p.light_ids())}, "
            f"culling={o['culling']!r}, stencil={o['stencil']!r})"
        )

    @property
    def options(self) -> Dict[str, Any]:
        """Every option's current value."""
        return json.loads(self._p.options())

    def set_options(self, **options: Any) -> None:
        """Changes the named options, keeping the others, the scene, the
        lights and the culling histories. With ``preset=``, the others
        start from that preset instead of their current values."""
        merged = {} if "preset" in options else self.options
        merged.update(options)
        self._p.set_options(_json("options", merged))

    # Scene -----------------------------------------------------------------

    def add_mesh(self, positions: Any, indices: Any, name: str = "mesh") -> MeshId:
        """Adds a mesh: ``positions`` an ``(n, 3)`` float32 or float64 array
        (any strides), ``indices`` an ``(m, 3)`` or ``(3m,)`` integer array.
        The library copies it once and welds its vertices. Returns its id.
        Sequences (nested lists, tuples) are taken as arrays."""
        if not isinstance(positions, np.ndarray):
            positions = np.asarray(positions, dtype=np.float64)
        if not isinstance(indices, np.ndarray):
            indices = np.asarray(indices, dtype=np.int64)
        return MeshId(self._p.add_mesh(positions, indices, name))

    def update_mesh_positions(self, mesh: MeshId, positions: Any, indices: Any) -> None:
        """Deforms ``mesh``: new positions, the same triangles."""
        self._p.update_mesh_positions(_handle(MeshId, "mesh", mesh), positions, indices)

    def remove_mesh(self, mesh: MeshId) -> None:
        """Removes a mesh no object draws any more."""
        self._p.remove_mesh(_handle(MeshId, "mesh", mesh))

    def add_object(
        self,
        mesh: MeshId,
        transform: Any = None,
        *,
        casts: bool = True,
        receives: bool = True,
        occludes: bool = True,
        visible: bool = True,
    ) -> ObjectId:
        """Adds an object drawing ``mesh`` at ``transform`` (4×4, world from
        local; identity when None). The flags say what it takes part in.
        Returns its id, valid until :meth:`remove_object`."""
        m = np.eye(4) if transform is None else _matrix("transform", transform)
        return ObjectId(
            self._p.add_object(_handle(MeshId, "mesh", mesh), m, casts, receives, occludes, visible)
        )

    def set_transform(self, obj: ObjectId, transform: Any) -> None:
        """Moves an object from the next frame on."""
        self._p.set_transform(_handle(ObjectId, "obj", obj), _matrix("transform", transform))

    def transform(self, obj: ObjectId) -> np.ndarray:
        """An object's world matrix (as of the last frame or edit)."""
        return self._p.transform(_handle(ObjectId, "obj", obj))

    def set_flags(
        self,
        obj: ObjectId,
        *,
        casts: Optional[bool] = None,
        receives: Optional[bool] = None,
        occludes: Optional[bool] = None,
        visible: Optional[bool] = None,
    ) -> None:
        """Sets the flags named (the others keep their values; see
        :meth:`flags`)."""
        old = self.flags(obj)
        new = dict(casts=casts, receives=receives, occludes=occludes, visible=visible)
        f = {k: old[k] if v is None else bool(v) for k, v in new.items()}
        self._p.set_flags(_handle(ObjectId, "obj", obj), f["casts"], f["receives"], f["occludes"], f["visible"])

    def flags(self, obj: ObjectId) -> Dict[str, bool]:
        """An object's flags: ``casts``, ``receives``, ``occludes`` and
        ``visible``."""
        casts, receives, occludes, visible = self._p.flags(_handle(ObjectId, "obj", obj))
        return dict(casts=casts, receives=receives, occludes=occludes, visible=visible)

    def set_occluder(self, obj: ObjectId, mesh: "MeshId | None" = None) -> None:
        """Gives an object the host's own occluder: ``mesh`` (from
        :meth:`add_mesh`, placed by the object's transform) is drawn in place
        of its mesh by the light views and a coarse eye pass under
        ``occluders="proxy"``. It must hide nothing the object does not (lie
        inside its solid); its bounds must lie within the object's mesh's
        (``ValueError`` otherwise). ``None`` goes back to the object's own
        mesh."""
        self._p.set_occluder(_handle(ObjectId, "obj", obj), None if mesh is None else _handle(MeshId, "mesh", mesh))

    def set_mesh(self, obj: ObjectId, mesh: MeshId) -> None:
        """Gives an object another mesh (a level-of-detail change); its id,
        flags, transform and occluder stay."""
        self._p.set_mesh(_handle(ObjectId, "obj", obj), _handle(MeshId, "mesh", mesh))

    def remove_object(self, obj: ObjectId) -> None:
        """Removes an object; its id is stale afterwards."""
        self._p.remove_object(_handle(ObjectId, "obj", obj))

    def load(self, path: "os.PathLike[str] | str") -> Loaded:
        """Adds every object of a glTF (``.gltf``, ``.glb``), OBJ (``.obj``
        or a directory of them) or box-city (``.txt``) file."""
        return _loaded(*self._p.load(os.fspath(path)))

    def add_city(self, **params: Any) -> Loaded:
        """Adds the procedural city (the RON job's ``City(...)`` scene) with
        its cameras, paths (``street``, ``bird``) and lights (``light``,
        ``sun``): keywords are its parameters (``seed``, ``blocks_x``,
        ``blocks_z``, ``block_size``, ...), each defaulted (20 × 20 blocks,
        about 17,400 objects)."""
        return _loaded(*self._p.add_city(_json("city", params)))

    @property
    def bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """World bounds ``(min, max)`` of the objects as of the last frame
        and of every file loaded since."""
        lo, hi = self._p.bounds()
        return np.array(lo), np.array(hi)

    def path_camera(self, name: str, frame: int) -> Optional[Dict[str, Any]]:
        """The pose of a loaded camera path at ``frame`` (None past its end)."""
        pose = self._p.path_camera(name, _index("frame", frame))
        return None if pose is None else json.loads(pose)

    # Lights ----------------------------------------------------------------

    @staticmethod
    def _light_spec(kind: str, value: Any, fields: Dict[str, Any]) -> str:
        variant = _LIGHT_VARIANTS.get(kind)
        if variant is None:
            raise ValueError(f"light: unknown kind {kind!r} (one of {', '.join(_LIGHT_VARIANTS)})")
        if kind in _LIGHT_VALUE:
            key = _LIGHT_VALUE[kind]
            if value is None:
                value = fields.pop(key, None)
            if value is None or fields:
                raise ValueError(
                    f"light {kind!r}: takes one value ({key}=...), got {sorted(fields) or 'none'}"
                )
            return _json("light", {variant: value})
        if value is not None:
            raise ValueError(f"light {kind!r}: takes keywords only")
        return _json("light", {variant: fields})

    def add_light(self, kind: str, value: Any = None, **fields: Any) -> LightId:
        """Adds a light, spelled as in a RON job and returns its id:

        - ``add_light("point", position=(x, y, z), range=None)``
        - ``add_light("spot", position=..., direction=..., apex_deg=40, range=None)``
        - ``add_light("directional", (dx, dy, dz))`` (the direction light travels)
        - ``add_light("sun", elevation_deg=35, azimuth_deg=30)``
        - ``add_light("above_scene", 1.5)`` (a point light above the scene bounds)
        - ``add_light("named", "light")`` (a light a loaded file names)
        """
        return LightId(self._p.add_light(self._light_spec(kind, value, fields)))

    def set_light(self, light: LightId, kind: str, value: Any = None, **fields: Any) -> None:
        """Replaces a light (same spelling as :meth:`add_light`)."""
        self._p.set_light(_handle(LightId, "light", light), self._light_spec(kind, value, fields))

    def remove_light(self, light: LightId) -> None:
        """Removes a light; its id is stale afterwards."""
        self._p.remove_light(_handle(LightId, "light", light))

    def light(self, light: LightId) -> Dict[str, Any]:
        """A light as the library holds it (``{"Point": {...}}``, ...)."""
        return json.loads(self._p.light(_handle(LightId, "light", light)))

    @property
    def lights(self) -> List[LightId]:
        """The live lights' ids."""
        return [LightId(b) for b in self._p.light_ids()]

    # Frames ----------------------------------------------------------------

    def set_frame_number(self, frame: int) -> None:
        """The job frame number of the next frame (culling coherence follows
        numbers, not calls: a jump starts a new history)."""
        self._p.set_frame_number(_index("frame", frame))

    def reserve(self, objects: int, lights: int) -> None:
        """Makes room for ``objects`` objects and ``lights`` lights in all:
        adding up to that many allocates nothing, and objects added into the
        room refit the culling hierarchy instead of rebuilding it."""
        self._p.reserve(_index("objects", objects), _index("lights", lights))

    def reset_history(self) -> None:
        """Forgets the culling histories and caches (a camera cut)."""
        self._p.reset_history()

    def frame(
        self,
        width: int,
        height: int,
        *,
        camera: Optional[Dict[str, Any]] = None,
        view: Any = None,
        projection: Any = None,
        clip_depth: str = "negative_one_to_one",
        host_depth: Any = None,
        near: Optional[float] = None,
        anamorphic: bool = False,
    ) -> Frame:
        """Computes one ``width × height`` frame seen by ``camera`` (a
        :func:`look_at` pose) or by the host's ``view`` and perspective
        ``projection`` matrices (right-handed; ``clip_depth`` is
        ``"negative_one_to_one"`` for OpenGL, ``"zero_to_one"`` for
        Direct3D, Vulkan and Metal).

        ``host_depth``: the host's own depth of this frame, an ``(h, w)``
        array at the culling size (reversed Z, ``near / view distance``, 0
        where nothing was drawn; per pixel the farthest over the output
        pixels whose centres it holds). The eye pass then only queries it.

        ``near``: the near plane the host built ``projection`` with. When
        given, a projection whose near plane under ``clip_depth`` differs
        (a wrong convention, which the matrix alone cannot show) is a
        ``ValueError``.

        ``anamorphic``: the viewport's pixels are not square. Otherwise a
        ``width / height`` more than 1 % from the projection's aspect is a
        ``ValueError`` naming ``viewport`` (a projection made for another
        viewport size)."""
        cam = None if camera is None else _camera(camera)
        v = None if view is None else _matrix("view", view)
        p = None if projection is None else _matrix("projection", projection)
        d = None
        if host_depth is not None:
            d = np.ascontiguousarray(host_depth, dtype=np.float32)
            if d.ndim != 2:
                raise ValueError(f"host_depth: an (h, w) array, got shape {d.shape}")
        w, h = _index("width", width), _index("height", height)
        n = None if near is None else float(near)
        return Frame(self._p.frame(w, h, cam, v, p, clip_depth, d, n, bool(anamorphic)))

    def reference_mask(self, light: LightId) -> ReferenceMask:
        """The exact ray-cast mask of ``light`` for the last frame: what every
        culling and stencil option is measured against."""
        mask, ambiguous = self._p.reference_mask(_handle(LightId, "light", light))
        return ReferenceMask(mask, ambiguous)


# Batch jobs -----------------------------------------------------------------


def run_job(
    path: "os.PathLike[str] | str | None" = None,
    *,
    out: "os.PathLike[str] | str",
    frames: Optional[int] = None,
    shard: Optional[Tuple[int, int]] = None,
    warmup: Optional[int] = None,
    keyframe: Optional[int] = None,
    max_memory: "int | str | None" = None,
) -> Dict[str, Any]:
    """Runs a RON job (the bundled default when ``path`` is None) into the
    directory ``out``, as ``shadowcull run`` does; returns ``summary.json``.

    ``frames`` cuts the run to its first frames; ``shard=(i, n)`` runs the
    i-th of n blocks of frames (after ``warmup`` frames that prime culling
    and are not written); ``keyframe`` resets the histories every k frames;
    ``max_memory`` (bytes, or ``"8G"``) overrides the job's memory limit.
    """
    p = None if path is None else os.fspath(path)
    limit = None if max_memory is None else str(max_memory)
    return json.loads(_native.run_job(p, os.fspath(out), frames, shard, warmup, keyframe, limit))


def merge(out: "os.PathLike[str] | str", dirs: Iterable["os.PathLike[str] | str"]) -> Dict[str, Any]:
    """Merges the shard directories ``dirs`` of one job into ``out``, as
    ``shadowcull merge`` does; returns what it wrote."""
    return json.loads(_native.merge(os.fspath(out), [os.fspath(d) for d in dirs]))
