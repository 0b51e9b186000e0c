"""Camera sensors of any MjModel: RGB, metric depth, segmentation, intrinsics and poses.

One :class:`SensorRenderer` (one offscreen OpenGL context) renders all cameras of a model with
MuJoCo's classic renderer, without shadows, reflections, haze or decor, showing geom groups 0-2
only (group 3 holds collision geoms) and no sites. :class:`RgbdCamera` adds the structured-light
depth noise of :mod:`ipbench.envs.sensors.depth_noise`. Headless use needs ``MUJOCO_GL=egl`` (or
``osmesa``) set before MuJoCo is imported.

Conventions: images are (H, W[, C]) with row 0 at the top; depth is the z-depth along the
optical axis in metres, 0 where nothing was hit; poses are world-from-camera 4x4 matrices in
the OpenCV camera convention (x right, y down, z forward), whereas MuJoCo cameras look along
their -z with +y up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from .depth_noise import DepthNoiseModel, SensorError

__all__ = [
    "CameraIntrinsics",
    "RgbdCamera",
    "SensorError",
    "SensorRenderer",
    "camera_id",
    "camera_pose",
    "fit_offscreen",
    "intrinsics",
    "specular_geoms",
]

Camera = str | int  # a camera's name or id
Rgbd = tuple[np.ndarray, np.ndarray]  # (H, W, 3) uint8 colour, (H, W) float32 depth in m
_VISIBLE_GEOM_GROUPS = (0, 1, 2)  # group 3: collision geoms, never rendered
_CATMASK = mujoco.mjtCatBit.mjCAT_STATIC | mujoco.mjtCatBit.mjCAT_DYNAMIC  # no decor
_SKYBOX_RADIUS = 0.7  # skybox radius in mjr_render, as a fraction of the far plane
_BUFFERS = [((3,), np.uint8), ((), np.float32), ((), np.float64)]  # rgb, raw depth, float64
_CV_FROM_MJ = np.array([1.0, -1.0, -1.0])  # flips camera y and z axes (column scaling)


def camera_id(model: mujoco.MjModel, camera: Camera) -> int:
    """Id of a camera given by name or id; raises :class:`SensorError` listing the cameras."""
    names = [model.camera(i).name for i in range(model.ncam)]
    if isinstance(camera, str):
        cid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        if cid >= 0:
            return cid
    elif isinstance(camera, (int, np.integer)) and 0 <= camera < model.ncam:
        return int(camera)
    raise SensorError(
        f"unknown camera {camera!r}; valid: the model's cameras {names} or ids "
        f"0 to {model.ncam - 1}"
    )


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics of an image: size (px), focal lengths (px), principal point (px).

    Pixel (u, v) = (column, row) has its centre at integer coordinates, so a camera-frame
    point (x, y, z) (OpenCV convention) projects to ``u = fx x / z + cx``, ``v = fy y / z + cy``.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def K(self) -> np.ndarray:  # noqa: N802
        """(3, 3) float64 camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


def intrinsics(model: mujoco.MjModel, camera: Camera, width: int, height: int) -> CameraIntrinsics:
    """:class:`CameraIntrinsics` of a camera rendered at ``width`` x ``height`` px.

    Taken from the frustum MuJoCo renders with (``mjv_cameraFrustum``): from ``cam_fovy``
    (vertical field of view, square pixels, principal point at ``((W - 1) / 2, (H - 1) / 2)``),
    or, for cameras defined with ``sensorsize`` and ``focal``/``focalpixel``/``principal``, from
    ``cam_sensorsize`` and ``cam_intrinsic``; those keep their horizontal field of view, so
    ``fx != fy`` unless ``width / height`` matches the sensor's aspect ratio.
    """
    cid = camera_id(model, camera)
    _check_size(model, width, height)
    if model.cam_projection[cid] == mujoco.mjtProjection.mjPROJ_ORTHOGRAPHIC:
        raise SensorError(f"camera {camera!r} is orthographic; valid: perspective cameras")
    cam = _fixed_camera(cid)
    zver, zhor, zclip = (np.zeros(2, np.float32) for _ in range(3))
    mujoco.mjv_cameraFrustum(zver, zhor, zclip, model, cam)
    near, bottom, top = float(zclip[0]), -float(zver[1]), float(zver[0])
    if zhor.any():  # as mjv_updateCamera and mjr_render: fixed horizontal extent
        left, right = -float(zhor[0]), float(zhor[1])
    else:  # horizontal extent from the viewport aspect ratio (float32, as in mjr_render)
        half = float(np.float32(0.5) * np.float32(width / height) * np.float32(top - bottom))
        left, right = -half, half
    # glFrustum(left, right, bottom, top, near) maps the near-plane window to the viewport;
    # pixel centres are at +0.5 and image rows run top-down.
    return CameraIntrinsics(
        width=width,
        height=height,
        fx=width * near / (right - left),
        fy=height * near / (top - bottom),
        cx=width * -left / (right - left) - 0.5,
        cy=height * top / (top - bottom) - 0.5,
    )


def camera_pose(model: mujoco.MjModel, data: mujoco.MjData, camera: Camera) -> np.ndarray:
    """(4, 4) float64 world-from-camera pose, OpenCV convention; needs ``mj_forward``'d data."""
    cid = camera_id(model, camera)
    pose = np.eye(4)
    pose[:3, :3] = data.cam_xmat[cid].reshape(3, 3) * _CV_FROM_MJ
    pose[:3, 3] = data.cam_xpos[cid]
    return pose


def specular_geoms(model: mujoco.MjModel, threshold: float = 0.5) -> np.ndarray:
    """(ngeom,) bool: geoms whose material has ``mat_specular >= threshold`` (no material: no)."""
    matid = model.geom_matid
    return (matid >= 0) & (model.mat_specular[np.maximum(matid, 0)] >= threshold)


def _fixed_camera(cid: int) -> mujoco.MjvCamera:
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
    cam.fixedcamid = cid
    return cam


def _check_size(model: mujoco.MjModel, width: int, height: int) -> None:
    offw, offh = model.vis.global_.offwidth, model.vis.global_.offheight
    if not (isinstance(width, (int, np.integer)) and isinstance(height, (int, np.integer))):
        raise SensorError(f"width and height must be ints, got {width!r}, {height!r}")
    if not (0 < width <= offw and 0 < height <= offh):
        raise SensorError(
            f"resolution {width}x{height} is outside the offscreen buffer (1-{offw})x(1-{offh});"
            f' raise it in the model XML: <visual><global offwidth="{max(width, offw)}"'
            f' offheight="{max(height, offh)}"/></visual>'
        )


def fit_offscreen(model: mujoco.MjModel, width: int, height: int) -> None:
    """Raise ``model``'s offscreen buffer to at least ``width`` x ``height`` px (never lowers
    it), so a :class:`SensorRenderer` created afterwards renders images of that size; the
    buffer caps the largest image, it does not change what a smaller one shows."""
    if not (isinstance(width, (int, np.integer)) and isinstance(height, (int, np.integer))):
        raise SensorError(f"width and height must be ints, got {width!r}, {height!r}")
    if width < 1 or height < 1:
        raise SensorError(f"resolution {width}x{height}; valid: width and height >= 1 px")
    g = model.vis.global_
    g.offwidth, g.offheight = max(int(g.offwidth), int(width)), max(int(g.offheight), int(height))


def _owned(cls: type) -> type:
    """GLContext subclass without ``__del__``: its owner frees it after the MjrContext."""
    return type(f"_Owned{cls.__name__}", (cls,), {"__del__": lambda self: None})


class SensorRenderer:
    """Renders the cameras of ``model`` with one offscreen OpenGL context; not thread-safe.

    Images are at most ``model.vis.global_.offwidth`` x ``offheight`` px; ``max_geom`` is the
    scene's capacity (visual geoms per frame). Each render is one ``mjr_render`` pass. Free the
    context with :meth:`close` (or ``with``).
    """

    def __init__(self, model: mujoco.MjModel, max_geom: int = 10000) -> None:
        self._gl = self._con = None
        self.model = model
        self._gl = _owned(mujoco.GLContext)(model.vis.global_.offwidth, model.vis.global_.offheight)
        self._gl.make_current()
        self._con = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100)
        self._con.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        self._scene = mujoco.MjvScene(model, maxgeom=max_geom)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        self._scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        self._scene.flags[mujoco.mjtRndFlag.mjRND_HAZE] = False  # it writes depth at ~0.5 zfar
        self._opt = mujoco.MjvOption()
        self._opt.geomgroup[:] = 0
        self._opt.geomgroup[list(_VISIBLE_GEOM_GROUPS)] = 1
        self._opt.sitegroup[:] = 0
        self._opt.flags[mujoco.mjtVisFlag.mjVIS_RANGEFINDER] = False
        self._skybox = bool((model.tex_type == mujoco.mjtTexture.mjTEXTURE_SKYBOX).any())
        self._cam = _fixed_camera(0)
        self._buffers: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def render_rgb(
        self, data: mujoco.MjData, camera: Camera, width: int, height: int
    ) -> np.ndarray:
        """(H, W, 3) uint8 colour image of ``camera`` (a name or id)."""
        rgb = self._render(data, camera, width, height, read_depth=False)[0]
        return rgb[::-1].copy()

    def render_rgbd(self, data: mujoco.MjData, camera: Camera, width: int, height: int) -> Rgbd:
        """Colour (H, W, 3) uint8 and z-depth (H, W) float32 in m, read from one pass.

        Depth is 0 where nothing was hit: at the far plane (``zfar * extent``) and, if the model
        has a skybox, beyond ``0.7 zfar * extent * cos(angle of the image corners)`` (the skybox
        is drawn, with depth, at 0.7 of the far plane).
        """
        rgb, raw, buf = self._render(data, camera, width, height, read_depth=True)
        return rgb[::-1].copy(), self._metric_depth(raw[::-1], buf)

    def render_depth(
        self,
        data: mujoco.MjData,
        camera: Camera,
        width: int,
        height: int,
        offset: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> np.ndarray:
        """(H, W) float32 z-depth (m, 0 = nothing hit) of ``camera`` moved by ``offset``.

        ``offset`` (m) is along the camera's own axes, OpenCV convention (x right, y down, z
        forward), e.g. ``(0.075, 0, 0)`` for a structured-light projector beside the camera;
        orientation and intrinsics stay those of ``camera``. Depth only (no colour read-back).
        """
        offset = np.asarray(offset, dtype=np.float64)
        if offset.shape != (3,) or not np.isfinite(offset).all():
            raise SensorError(f"offset must be 3 finite floats (m, camera frame), got {offset!r}")
        raw, buf = self._render(data, camera, width, height, read_depth=True, offset=offset)[1:]
        return self._metric_depth(raw[::-1], buf)

    def render_segmentation(
        self, data: mujoco.MjData, camera: Camera, width: int, height: int
    ) -> np.ndarray:
        """(H, W) int32 geom id per pixel (np.ndarray); -1: no geom (background, flex, skin)."""
        rgb = self._render(data, camera, width, height, read_depth=False, segment=True)[0]
        ids = rgb[::-1, :, 2].astype(np.int32)  # segment id + 1, packed in the colour
        ids <<= 8
        ids |= rgb[::-1, :, 1]
        ids <<= 8
        ids |= rgb[::-1, :, 0]
        scene, ngeom = self._scene, self._scene.ngeom
        lut = np.full(ngeom + 2, -1, np.int32)  # [segid + 1] -> geom id; 0 and > ngeom: -1
        for i in range(ngeom):
            geom = scene.geoms[i]
            if geom.objtype == mujoco.mjtObj.mjOBJ_GEOM and geom.segid >= 0:
                lut[geom.segid + 1] = geom.objid
        return lut.take(ids, mode="clip")

    def close(self) -> None:
        """Free the OpenGL resources; idempotent. The renderer is unusable afterwards."""
        if self._con is not None and self._gl is not None:
            with self._gl.as_current():  # the MjrContext's GL objects belong to this context
                self._con.free()
        self._con = None
        if self._gl is not None:
            self._gl.free()
            self._gl = None

    def __enter__(self) -> SensorRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown: nothing left to report to
            pass

    def _render(
        self, data, camera, width, height, *, read_depth: bool, segment: bool = False, offset=None
    ):
        if self._con is None:
            raise SensorError("the SensorRenderer is closed; create a new one")
        self._cam.fixedcamid = camera_id(self.model, camera)
        _check_size(self.model, width, height)
        key = (int(height), int(width))
        if key not in self._buffers:  # reused: fresh large arrays cost page faults
            self._buffers[key] = tuple(np.empty(key + c, t) for c, t in _BUFFERS)
        rgb, raw, buf = self._buffers[key]
        self._gl.make_current()
        mujoco.mjv_updateScene(self.model, data, self._opt, None, self._cam, _CATMASK, self._scene)
        flags = self._scene.flags
        flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = segment
        if offset is not None and offset.any():  # move both GL eyes along the camera's axes
            for eye in self._scene.camera:
                fwd, up = np.array(eye.forward), np.array(eye.up)
                eye.pos = eye.pos + offset @ np.stack([np.cross(fwd, up), -up, fwd])
        rect = mujoco.MjrRect(0, 0, width, height)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._con)
        mujoco.mjr_render(rect, self._scene, self._con)
        colour = None if offset is not None else rgb
        mujoco.mjr_readPixels(colour, raw if read_depth else None, rect, self._con)
        return rgb, raw, buf

    def _metric_depth(self, raw: np.ndarray, buf: np.ndarray) -> np.ndarray:
        """Reversed-Z depth buffer (1 near, 0 far) to metres, exactly as ``mujoco.Renderer``."""
        extent, cam = self.model.stat.extent, self._scene.camera[0]
        znear = np.float32(self.model.vis.map.znear * extent)
        zfar = np.float32(self.model.vis.map.zfar * extent)
        np.copyto(buf, raw)
        if cam.orthographic:
            np.multiply(buf, -(zfar - znear), out=buf)
            buf += zfar
        else:
            c_coef = -(zfar + znear) / (zfar - znear)
            d_coef = -(np.float32(2) * zfar * znear) / (zfar - znear)
            c_coef = np.float32(-0.5) * c_coef - np.float32(0.5)  # reversed-Z projection
            d_coef = np.float32(-0.5) * d_coef
            buf += c_coef
            np.divide(d_coef, buf, out=buf)
        depth = buf.astype(np.float32)
        missing = raw == 0  # far plane: nothing hit
        if self._skybox and self._scene.flags[mujoco.mjtRndFlag.mjRND_SKYBOX]:
            # The skybox, a cylinder of radius 0.7 zfar around the camera, is drawn with depth:
            # its z-depth is >= 0.7 zfar cos(angle of the image corners to the optical axis).
            h, w = depth.shape
            half_w = cam.frustum_width or 0.5 * w / h * (cam.frustum_top - cam.frustum_bottom)
            tx = (abs(cam.frustum_center) + half_w) / cam.frustum_near
            ty = max(abs(cam.frustum_top), abs(cam.frustum_bottom)) / cam.frustum_near
            cos_corner = 1.0 if cam.orthographic else (1 + tx * tx + ty * ty) ** -0.5
            facets = math.cos(math.pi / max(3, self.model.vis.quality.numslices))  # polygonal
            missing |= depth > 0.99 * _SKYBOX_RADIUS * zfar * cos_corner * facets
        np.copyto(depth, 0, where=missing)
        return depth


class RgbdCamera:
    """An RGB-D sensor: a camera (name or id) of a shared renderer, a resolution (px) and noise.

    ``noise`` defaults to ``DepthNoiseModel()`` (Xtion); ``specular`` ((ngeom,) bool, which geoms
    are specular) to :func:`specular_geoms`, computed once. The specular mask costs a second
    render (segmentation), done only if the noise model uses it and some geom is specular.
    """

    def __init__(
        self,
        renderer: SensorRenderer,
        camera: Camera,
        width: int = 640,
        height: int = 480,
        noise: DepthNoiseModel | None = None,
        specular: np.ndarray | None = None,
    ) -> None:
        model = renderer.model
        self.renderer = renderer
        self.camera_id = camera_id(model, camera)
        self.name = model.camera(self.camera_id).name
        self.intrinsics = intrinsics(model, self.camera_id, width, height)
        self.noise = DepthNoiseModel() if noise is None else noise
        specular = specular_geoms(model) if specular is None else np.asarray(specular, bool)
        if specular.shape != (model.ngeom,):
            raise SensorError(f"specular must be a bool array of shape ({model.ngeom},)")
        self._specular_lut = np.append(specular, False)  # geom id -1 (background): not specular
        self.needs_segmentation = self.noise.uses_specular and bool(specular.any())

    def pose(self, data: mujoco.MjData) -> np.ndarray:
        """(4, 4) world-from-camera pose, OpenCV convention."""
        return camera_pose(self.renderer.model, data, self.camera_id)

    def capture(self, data: mujoco.MjData, rng: np.random.Generator) -> Rgbd:
        """Colour (H, W, 3) uint8 and noisy depth (H, W) float32 (m, 0 = missing)."""
        k = self.intrinsics
        rgb, depth = self.renderer.render_rgbd(data, self.camera_id, k.width, k.height)
        mask = None
        if self.needs_segmentation:
            seg = self.renderer.render_segmentation(data, self.camera_id, k.width, k.height)
            mask = self._specular_lut.take(seg)  # -1 wraps to the last entry
        depth = self.noise.apply(depth, k.fx, k.fy, rng, mask, cx=k.cx, cy=k.cy)
        return rgb, depth
