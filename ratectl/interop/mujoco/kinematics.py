"""MuJoCo and mink kinematics in ratectl's conventions: a frame's pose and Jacobian, and a
chain-compatible kinematics source backed by a ``mink.Configuration``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ...errors import InputError
from ...io.mjcf import mjcf_joint_addresses
from ...kinematics import check_frame, refer_jacobian
from ...model import Chain

if TYPE_CHECKING:
    import mink

__all__ = ['mujoco_fk_jacobian', 'MinkKinematics']


# ---------------------------------------------------------------------- kinematics
_FRAME_TYPES = ("site", "body")


def _frame_id(model, frame: str, frame_type: str) -> int:
    if frame_type not in _FRAME_TYPES:
        raise InputError(f"frame_type must be one of {_FRAME_TYPES}, got {frame_type!r}",
                         argument="frame_type", value=frame_type)
    obj = mujoco.mjtObj.mjOBJ_SITE if frame_type == "site" else mujoco.mjtObj.mjOBJ_BODY
    i = mujoco.mj_name2id(model, obj, frame)
    if i < 0:
        raise InputError(f"the model has no {frame_type} named {frame!r}", argument="frame", value=frame)
    return i


def mujoco_fk_jacobian(model: mujoco.MjModel, data: mujoco.MjData, chain: Chain, q: ArrayLike, *,
                       frame: str, frame_type: str = "site") -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's pose (4×4) and Jacobian (6×n, ratectl conventions) of a site or body at q.

    Sets the chain's joints of ``data.qpos`` to ``q`` (other joints keep their value),
    runs ``mj_kinematics`` and ``mj_comPos``, and returns ``T_world_frame`` and
    ``[jacp; jacr]`` restricted to the chain's dofs — world axes, linear part at the
    frame origin, i.e. exactly ``chain.fk(q)``/``chain.jacobian(q)`` when the chain
    describes the same arm.
    """
    qadr, dadr = mjcf_joint_addresses(model, chain)
    fid = _frame_id(model, frame, frame_type)
    data.qpos[qadr] = chain.check_q(q)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    jp = np.zeros((3, model.nv))
    jr = np.zeros((3, model.nv))
    if frame_type == "site":
        pos, mat = data.site_xpos[fid], data.site_xmat[fid]
        mujoco.mj_jacSite(model, data, jp, jr, fid)
    else:
        pos, mat = data.xpos[fid], data.xmat[fid]
        mujoco.mj_jacBody(model, data, jp, jr, fid)
    T = np.eye(4)
    T[:3, :3] = mat.reshape(3, 3)
    T[:3, 3] = pos
    return T, np.vstack([jp[:, dadr], jr[:, dadr]])


class MinkKinematics:
    """A chain-compatible kinematics source backed by a ``mink.Configuration``.

    ``fk``, ``jacobian`` and ``fk_jacobian`` are computed by MuJoCo through mink
    (``Configuration.update`` then ``get_transform_frame_to_world`` and
    ``get_frame_jacobian``); mink's body-frame Jacobian ``ᴮJ`` is converted to ratectl's
    convention by ``J = blockdiag(R, R) · ᴮJ`` (world axes, linear part at the frame
    origin) and restricted to the chain's dofs. Limits, names, ``dof`` and every
    other attribute come from ``chain`` (by default imported from the same model with
    `ratectl.Chain.from_mjcf`), so a
    `ResolvedRateController` can use this object in place of a chain.

    Joints of the model that are not in the chain keep their values in
    ``configuration.data.qpos`` (they are treated as fixed).

    Args:
        configuration: a ``mink.Configuration`` (or an ``MjModel``, wrapped in one).
        frame: name of the tool site or body.
        frame_type: ``"site"`` or ``"body"``.
        chain: the ratectl chain of the arm (joint names must match the model's).
    """

    def __init__(self, configuration: mink.Configuration, *, frame: str, frame_type: str = "site",
                 chain: Chain | None = None) -> None:
        import mink

        if isinstance(configuration, mujoco.MjModel):
            configuration = mink.Configuration(configuration)
        if not isinstance(configuration, mink.Configuration):
            raise InputError("configuration must be a mink.Configuration or a mujoco.MjModel, got "
                             f"{type(configuration).__name__}", argument="configuration",
                             value=configuration)
        self.configuration = configuration
        model = configuration.model
        _frame_id(model, frame, frame_type)
        if chain is None:
            chain = Chain.from_mjcf(model, tip=frame)
        self.chain = chain
        self.frame = frame
        self.frame_type = frame_type
        self.qpos_indices, self.dof_indices = mjcf_joint_addresses(model, chain)

    def __getattr__(self, name):
        # everything that is not kinematics (limits, names, dof, ...) comes from the chain
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.__dict__["chain"], name)

    def __repr__(self) -> str:
        return (f"MinkKinematics(frame={self.frame!r}, frame_type={self.frame_type!r}, "
                f"chain={self.chain!r})")

    def update(self, q: ArrayLike) -> None:
        """Set the chain joints to q (n,) and run mink's forward kinematics."""
        qfull = np.array(self.configuration.data.qpos, dtype=float)
        qfull[self.qpos_indices] = q
        self.configuration.update(qfull)

    def _single(self, q):
        self.update(q)
        cfg = self.configuration
        T = cfg.get_transform_frame_to_world(self.frame, self.frame_type).as_matrix()
        R = T[:3, :3]
        BJ = cfg.get_frame_jacobian(self.frame, self.frame_type)[:, self.dof_indices]
        J = np.empty_like(BJ)
        J[:3] = R @ BJ[:3]
        J[3:] = R @ BJ[3:]
        return T, J

    def fk_jacobian(self, q: ArrayLike, *, frame: str = "base",
                    point: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(T_world_frame, J)`` from MuJoCo via mink; ``frame``/``point`` as in
        `ratectl.Chain.jacobian`."""
        a = self.chain.check_q(q)
        batch = a.shape[:-1]
        flat = a.reshape(-1, a.shape[-1])
        Ts = np.empty((flat.shape[0], 4, 4))
        Js = np.empty((flat.shape[0], 6, flat.shape[1]))
        for k, qk in enumerate(flat):
            Ts[k], Js[k] = self._single(qk)
        T, J = Ts.reshape(batch + (4, 4)), Js.reshape(batch + Js.shape[1:])
        if frame != "base" or point is not None:
            check_frame(frame)
            J = refer_jacobian(J, T, frame, point)
        return T, J

    def fk(self, q: ArrayLike) -> np.ndarray:
        """Pose of the frame in the world (..., 4, 4), from MuJoCo."""
        return self.fk_jacobian(q)[0]

    def jacobian(self, q: ArrayLike, *, frame: str = "base", point: ArrayLike | None = None) -> np.ndarray:
        """Geometric Jacobian (..., 6, n) in ratectl's conventions, from mink/MuJoCo."""
        return self.fk_jacobian(q, frame=frame, point=point)[1]

    def body_jacobian(self, q: ArrayLike) -> np.ndarray:
        """mink's own body-frame Jacobian ᴮJ (6, n) at q (for cross-checks)."""
        self.update(q)
        return self.configuration.get_frame_jacobian(self.frame, self.frame_type)[:, self.dof_indices]
