"""Bodies, loads and the contact problem: small immutable objects."""

from __future__ import annotations

from dataclasses import InitVar, dataclass, field, replace
from functools import cached_property
from types import MappingProxyType

import numpy as np

from ._checks.inputs import SMALLEST, finite_number, vector3
from .errors import InputError
from .formulations._parts.resistance import require_finite, resistance, unresisted
from .formulations._parts.system import ROUNDING, SpringSystem
from .kinematics import DOF_NAMES, DOFS, normal_operator
from .laws import Law, check_law
from .layer import SpringLayer

__all__ = ["DOFS", "Body", "ContactProblem", "Load"]


@dataclass(frozen=True)
class Load:
    """A force (N) and moment (N mm) on a body; with ``point`` the force acts there.

    Parameters
    ----------
    force : array_like, shape (3,)
        Force in N.
    moment : array_like, shape (3,) or 0
        Moment in N mm about the body's reference point.
    point : array_like, shape (3,), optional
        Where the force acts (mm); its moment about the reference is added.
    """

    force: tuple = (0.0, 0.0, 0.0)
    moment: tuple = (0.0, 0.0, 0.0)
    point: tuple | None = None

    def __post_init__(self):
        object.__setattr__(self, "force", vector3("force", self.force, "N"))
        object.__setattr__(self, "moment", vector3("moment", self.moment, "N mm"))
        if self.point is not None:
            object.__setattr__(self, "point", vector3("point", self.point, "mm"))

    def about(self, reference) -> tuple[tuple, tuple]:
        """``(force, moment)`` with the moment taken about ``reference``."""
        moment = np.array(self.moment)
        if self.point is not None:
            moment = moment + np.cross(np.subtract(self.point, reference), self.force)
        return self.force, tuple(float(v) for v in moment)


def _dof_tuple(name: str, value) -> tuple:
    if value is None:
        return ()
    if isinstance(value, str):
        value = (value,) if value not in ("all", "none") else (DOFS if value == "all" else ())
    try:
        items = tuple(value)
    except TypeError:
        raise InputError(f"{name} must be a sequence of dof names from {DOFS}, got {value!r}") from None
    for item in items:
        if item not in DOFS:
            raise InputError(f"{name} must hold dof names from {DOFS}, got {item!r}")
    if len(set(items)) != len(items):
        raise InputError(f"{name} lists a dof twice: {items}")
    return tuple(d for d in DOFS if d in items)


class _Unprescribed(tuple):
    """The default of :attr:`Body.free`: every dof the body does not prescribe (told apart from a
    ``free`` the caller gave by its type)."""


@dataclass(frozen=True)
class Body:
    """One rigid bone: its reference point, free dofs, load and prescribed motion.

    Parameters
    ----------
    reference : array_like, shape (3,)
        The point rotations are about and moments are taken about (mm); the body
        centroid of Eq. (10).
    free : sequence of str, optional
        Unknown dofs among ``("ux", "uy", "uz", "rx", "ry", "rz")``; default every dof that is
        not prescribed. Dofs neither free nor prescribed are fixed at zero.
    force, moment : array_like, shape (3,)
        Load on the body (N and N mm about ``reference``).
    prescribed : mapping {dof: value}
        Dofs held at a given displacement (mm or rad); their reactions are reported. A dof
        cannot be both: one listed in ``free`` and in ``prescribed`` is an :class:`InputError`.
    """

    reference: tuple = (0.0, 0.0, 0.0)
    free: tuple = _Unprescribed(DOFS)
    force: tuple = (0.0, 0.0, 0.0)
    moment: tuple = (0.0, 0.0, 0.0)
    prescribed: dict = field(default_factory=dict)

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "reference", vector3("reference", self.reference, "mm"))
        set_(self, "force", vector3("force", self.force, "N"))
        set_(self, "moment", vector3("moment", self.moment, "N mm"))
        if not hasattr(self.prescribed, "items"):
            raise InputError(f"prescribed must be a mapping {{dof: value}}, got {self.prescribed!r}")
        prescribed = {}
        for dof, value in self.prescribed.items():
            if dof not in DOFS:
                raise InputError(f"prescribed must use dof names from {DOFS}, got {dof!r}")
            prescribed[dof] = finite_number(f"prescribed[{dof!r}]", value, "mm or rad")
        set_(self, "prescribed", MappingProxyType(prescribed))
        if isinstance(self.free, _Unprescribed):
            set_(self, "free", tuple(d for d in DOFS if d not in prescribed))
            return
        free = _dof_tuple("free", self.free)
        both = [d for d in free if d in prescribed]
        if both:
            raise InputError(
                f"a dof cannot be both free and prescribed: {', '.join(both)} "
                f"(free={free}, prescribed={dict(prescribed)}); remove it from one of them"
            )
        set_(self, "free", free)

    def __reduce__(self):
        # the checked values again through the constructor (a mappingproxy does not pickle)
        return (Body, (self.reference, self.free, self.force, self.moment, dict(self.prescribed)))

    def with_load(self, load: Load | None = None, *, force=None, moment=None, point=None) -> Body:
        """A copy carrying ``load`` (or the load made of ``force``, ``moment``, ``point``)."""
        if load is None:
            load = Load(force=force, moment=moment, point=point)
        elif not isinstance(load, Load):
            raise InputError(f"load must be a dea_opt.Load, got {type(load).__name__}")
        f, m = load.about(self.reference)
        return replace(self, force=f, moment=m, prescribed=dict(self.prescribed))

    def with_prescribed(self, **values) -> Body:
        """A copy with these dofs prescribed (e.g. ``uz=-0.2``): free ones are free no more."""
        prescribed = {**self.prescribed, **values}
        free = tuple(d for d in self.free if d not in values)
        return replace(self, free=free, prescribed=prescribed)

    @property
    def load_vector(self) -> np.ndarray:
        """``(Fx, Fy, Fz, Mx, My, Mz)`` of Eq. (8)."""
        return np.array(self.force + self.moment)


FIXED = Body(free=())
#: Body 2's default: free in every dof, unloaded, its reference at the origin.
_FREE = Body()


@dataclass(frozen=True, eq=False)
class ContactProblem:
    """Two rigid bodies touching through a spring layer.

    Parameters
    ----------
    layer : SpringLayer
    law : Law
    body1, body2 : Body
        Default: body 1 fixed, body 2 free in all six dofs.
    force, moment, reference, free, load :
        Shorthand for body 2 with body 1 fixed: ``ContactProblem(layer, law,
        force=(0, 0, -500), reference=(0, 0, 0), free=("uz", "rx", "ry"))``.
        ``load`` is a :class:`Load` (use it for a force acting at a point).
    kinematics : {"small", "finite"}
        ``"small"`` (default): the linearised rigid motion of Eq. (9)-(11), gaps cast once.
        ``"finite"``: body 2 moves by the exact rotation of its rotation vector ``u[9:12]``
        about its reference plus ``u[6:9]``, each spring's gap is taken to its target at that
        pose, and springs cast from meshes are re-cast as body 2 moves
        (``formulations/finite.md``). Body 1 stays fixed; the load on body 2 is a force at its
        reference and a moment, both constant in space.
    targets : Targets, SpringCast or None
        Finite kinematics only: each spring's target on body 2. A
        :class:`~dea_opt.mesh.SpringCast` (the cast that made ``layer``) gives the tangent
        planes of the faces its rays met and lets the solver re-cast; ``None`` takes the layer's
        own targets when it was cast from meshes, else each spring's own plane (through
        ``p + gap n``, normal ``-n``); :class:`~dea_opt.formulations.finite.Targets` gives
        planes or spheres explicitly.
    """

    layer: SpringLayer
    law: Law
    body1: Body = FIXED
    body2: Body = _FREE  # the default stands for "not given": the shorthand builds it
    force: InitVar = None
    moment: InitVar = None
    reference: InitVar = None
    free: InitVar = None
    load: InitVar = None
    kinematics: str = "small"
    targets: object = None

    def __post_init__(self, force, moment, reference, free, load):
        _check_kinematics(self.kinematics, self.targets)
        if not isinstance(self.layer, SpringLayer):
            raise InputError(f"layer must be a SpringLayer, got {type(self.layer).__name__}")
        check_law(self.law)
        if not isinstance(self.body1, Body):
            raise InputError(f"body1 must be a dea_opt.Body, got {type(self.body1).__name__}")
        shorthand = any(v is not None for v in (force, moment, reference, free, load))
        body2 = _FREE if self.body2 is None else self.body2  # None: as not given
        if shorthand:
            if body2 is not _FREE:
                raise InputError(
                    "give either body2=Body(...) or the shorthand force/moment/reference/free/load, not both"
                )
            body2 = Body(
                reference=(0.0, 0.0, 0.0) if reference is None else reference,
                free=DOFS if free is None else free,
                force=force,
                moment=moment,
            )
            if load is not None:
                body2 = body2.with_load(load)
        if not isinstance(body2, Body):
            raise InputError(f"body2 must be a dea_opt.Body, got {type(body2).__name__}")
        object.__setattr__(self, "body2", body2)
        _check_load_scale(self.load_vector)

    # --- copies -------------------------------------------------------------------------
    def with_load(self, load: Load | None = None, *, force=None, moment=None, point=None, body: int = 2):
        """A copy whose body ``body`` (1 or 2) carries a new load.

        The copy shares the spring arrays already built: a new load changes none of them, and
        a load path would otherwise rebuild an N x 12 array per frame.
        """
        key = _body_key(body)
        new = replace(self, **{key: getattr(self, key).with_load(load, force=force, moment=moment, point=point)})
        for name in _GEOMETRY_CACHE:
            if name in self.__dict__:
                new.__dict__[name] = self.__dict__[name]
        return new

    def with_law(self, law: Law) -> ContactProblem:
        return replace(self, law=law)

    def with_layer(self, layer: SpringLayer) -> ContactProblem:
        return replace(self, layer=layer)

    def with_body(self, body: int, new: Body) -> ContactProblem:
        return replace(self, body1=new) if _body_key(body) == "body1" else replace(self, body2=new)

    # --- derived arrays -----------------------------------------------------------------
    @cached_property
    def normal_operator(self) -> np.ndarray:
        """Rows ``n_i^T B_i`` (N, 12), see :mod:`dea_opt.kinematics`."""
        layer = self.layer
        return normal_operator(layer.points, layer.normals, self.body1.reference, self.body2.reference)

    @cached_property
    def free_indices(self) -> np.ndarray:
        """Indices into the 12-vector ``u`` of the free dofs."""
        idx = [i for i, d in enumerate(DOFS) if d in self.body1.free]
        idx += [6 + i for i, d in enumerate(DOFS) if d in self.body2.free]
        return np.array(idx, dtype=int)

    @property
    def free_names(self) -> tuple:
        return tuple(DOF_NAMES[i] for i in self.free_indices)

    @cached_property
    def prescribed_u(self) -> np.ndarray:
        """The 12-vector with prescribed values at their dofs and zeros elsewhere."""
        u = np.zeros(12)
        for k, body in enumerate((self.body1, self.body2)):
            for dof, value in body.prescribed.items():
                u[6 * k + DOFS.index(dof)] = value
        return u

    @property
    def load_vector(self) -> np.ndarray:
        """``r`` of Eq. (8), shape (12,)."""
        return np.concatenate([self.body1.load_vector, self.body2.load_vector])

    @cached_property
    def _geometry(self) -> tuple:
        GT = self.normal_operator.T
        h = self.layer.thickness
        AT = GT[self.free_indices] / h
        e0 = (self.layer.gap + self.prescribed_u @ GT) / h
        return AT, e0, self.layer.areas * h

    def system(self) -> SpringSystem:
        """The reduced problem over the free dofs, for the formulations."""
        AT, e0, volume = self._geometry
        lengths = np.concatenate(
            [np.ones(3), np.full(3, self.layer_radius[0]), np.ones(3), np.full(3, self.layer_radius[1])]
        )
        system = SpringSystem(
            AT,
            e0,
            volume,
            self.load_vector[self.free_indices],
            lengths[self.free_indices],
            self._factor,
            self._stiffness,
        )
        # Which directions the springs resist depends on the geometry only: decided once per
        # geometry and shared by every load (the cache is copied by with_load).
        if "_resistance" not in self.__dict__:
            self.__dict__["_resistance"] = resistance(system)
        system.__dict__["resistance"] = self.__dict__["_resistance"]
        return system

    @cached_property
    def _stiffness(self) -> float:
        """``sum_i S_i / h_i`` (mm): the layer's stiffness scale per unit modulus, against
        which directions are judged unresisted (:func:`~dea_opt.formulations._parts.resistance.unresisted`)."""
        return float(np.sum(self.layer.areas / self.layer.thickness))

    @cached_property
    def _factor(self) -> np.ndarray:
        """``F`` (r, m) with ``F^T F = A^T diag(V) A``, built in a well-conditioned basis.

        Every column of ``G`` is ``E c`` with ``E = [n, (x - g) x n]`` (translations, and
        rotations about the layer's centroid ``g``) and a small exact ``c``: a rotation about a
        reference ``c_k`` is the rotation about ``g`` plus the translation ``e x (g - c_k)``. So
        ``A^T diag(V) A = C^T M C`` with the 6 x 6 ``M = E^T diag(S / h) E``, whose conditioning
        does not suffer from references far from the layer (formulations/energy.md, "Scaling").
        """
        layer = self.layer
        m = len(self.free_indices)
        if not len(layer) or not m:
            return np.zeros((0, m))
        weight = layer.areas / layer.thickness
        g = weight @ layer.points / weight.sum()
        E = np.empty((6, len(layer)))
        E[:3] = layer.normals.T
        E[3:] = np.cross(layer.points - g, layer.normals).T
        M = (E * weight) @ E.T
        radius = float(np.sqrt(weight @ np.sum((layer.points - g) ** 2, axis=1) / weight.sum()))
        radius = radius if radius > 1e-100 else 1.0  # springs at one point resist no rotation
        Dg = np.array([1.0, 1.0, 1.0, radius, radius, radius])
        M = M / np.outer(Dg, Dg)
        require_finite("the layer's stiffness matrix", M)
        vals, vecs = np.linalg.eigh(M)
        # A Gram matrix holds rounding noise at about 1e-16 of its largest eigenvalue; the one
        # test of "unresisted", against the layer's stiffness sum S / h (the trace of M's
        # translation block), drops those directions (formulations/energy.md).
        keep = ~unresisted(vals, max(float(weight.sum()), float(vals[-1])))
        L = Dg[:, None] * vecs[:, keep] * np.sqrt(vals[keep])  # M = L L^T
        C = np.zeros((6, m))
        for col, j in enumerate(self.free_indices):
            body, k = divmod(int(j), 6)
            sign = 1.0 if body == 1 else -1.0
            reference = np.asarray((self.body1, self.body2)[body].reference)
            if k < 3:
                C[k, col] = sign
            else:
                e = np.zeros(3)
                e[k - 3] = 1.0
                C[:3, col] = sign * np.cross(e, g - reference)
                C[3 + k - 3, col] = sign
        return L.T @ C

    def full_u(self, x) -> np.ndarray:
        """The 12-vector ``u`` from the free-dof vector ``x``."""
        u = self.prescribed_u.copy()
        u[self.free_indices] = x
        return u

    def strain(self, u) -> np.ndarray:
        """``eps_i = (gap_i + n_i . B_i u) / h_i`` (Eq. 11), shape (N,)."""
        return (self.layer.gap + np.asarray(u, dtype=float) @ self.normal_operator.T) / self.layer.thickness

    def strain_rounding(self, u) -> np.ndarray:
        """A bound on the rounding of :meth:`strain` at ``u``, shape (N,): ``ROUNDING`` ulps of the
        sizes of the terms the strain is summed from, ``(|gap_i| + sum_k |t_k|_1 + |p_i - c_k|
        |w_k|_1) / h_i`` (``t_k``, ``w_k`` body ``k``'s translation and rotation; a row of the
        normal operator is at most 1 per translation and ``|p_i - c_k|`` per rotation). Where
        ``gap`` and the motion nearly cancel (a layer that starts in deep overlap and separates),
        the strain keeps only the digits these leave (formulations/energy.md, "The certificate")."""
        u = np.asarray(u, dtype=float)
        size = np.abs(self.layer.gap)
        for k, arm in enumerate(self._arm_lengths):
            size = size + (
                float(np.abs(u[6 * k : 6 * k + 3]).sum()) + arm * float(np.abs(u[6 * k + 3 : 6 * k + 6]).sum())
            )
        return ROUNDING * np.finfo(float).eps * size / self.layer.thickness

    @cached_property
    def _arm_lengths(self) -> tuple[np.ndarray, np.ndarray]:
        """``|p_i - c_k|`` for the two bodies' references (mm), each shape (N,)."""
        points = self.layer.points
        return tuple(
            np.linalg.norm(points - np.asarray(b.reference, dtype=float), axis=1) for b in (self.body1, self.body2)
        )

    @cached_property
    def layer_radius(self) -> np.ndarray:
        """RMS distance of the springs from each body's reference (mm), shape (2,)."""
        points = self.layer.points
        if not len(points):
            return np.ones(2)
        mean, mean_sq = points.mean(axis=0), float(np.mean(np.einsum("ij,ij->i", points, points)))
        radius = []
        for body in (self.body1, self.body2):
            c = np.asarray(body.reference)
            radius.append(max(np.sqrt(max(mean_sq - 2 * c @ mean + c @ c, 0.0)), 1e-12))
        return np.array(radius)

    def __repr__(self) -> str:
        kinematics = ", kinematics='finite'" if self.kinematics == "finite" else ""
        return (
            f"ContactProblem({self.layer!r}, {self.law.describe()}, free={self.free_names}, "
            f"load={self.load_vector.round(6).tolist()}{kinematics})"
        )


#: Cached properties that depend on the layer, the references and the free and prescribed
#: dofs only, never on the loads.
_GEOMETRY_CACHE = (
    "normal_operator",
    "free_indices",
    "prescribed_u",
    "_geometry",
    "layer_radius",
    "_factor",
    "_stiffness",
    "_resistance",
    "_arm_lengths",
)


KINEMATICS = ("small", "finite")


def _check_kinematics(kinematics, targets) -> None:
    """``kinematics`` is "small" or "finite"; ``targets`` only with "finite", and of a known kind."""
    if not isinstance(kinematics, str) or kinematics not in KINEMATICS:
        raise InputError(f"kinematics must be one of {KINEMATICS}, got {kinematics!r}")
    if targets is None:
        return
    if kinematics != "finite":
        raise InputError(
            "targets are for kinematics='finite' (the small kinematics of Eq. 9-11 use the layer's "
            "gaps only): pass kinematics='finite' or leave targets out"
        )
    from .formulations.finite.geometry import Targets
    from .mesh.springs import SpringCast

    if not isinstance(targets, (Targets, SpringCast)):
        raise InputError(
            f"targets must be a dea_opt.formulations.finite.Targets, a dea_opt.mesh.SpringCast or None, "
            f"got {type(targets).__name__}"
        )


def _check_load_scale(load: np.ndarray) -> None:
    """A nonzero load sets the scale the formulations solve in: its largest component must be
    at least :data:`~dea_opt._checks.inputs.SMALLEST` (0 means no load)."""
    top = float(np.abs(load).max(initial=0.0))
    if 0.0 < top < SMALLEST:
        raise InputError(
            f"the load's largest component is {top:g} (N or N mm): a nonzero load must reach at least "
            f"{SMALLEST:g} in some component (it sets the scale the problem is solved in); use 0 for no load"
        )


def _body_key(body) -> str:
    if body not in (1, 2):
        raise InputError(f"body must be 1 or 2, got {body!r}")
    return f"body{body}"
