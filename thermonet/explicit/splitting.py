"""Explicit integrators as kick/drift splittings (Mata & Lew 2011: GTR-0/1 (51)–(52), CO2/F10 (64)–(66), NM2 §4.2),
and higher-order compositions of CO2 (CO4, CO6).

A scheme ``K(k0) D(d0) K(k1) … D(d_{S−1}) K(k_S)`` is data: the ``kicks`` (S+1) and ``drifts`` (S)
coefficients, as fractions of h. See :mod:`thermonet.explicit.cpu` for what a kick and a
drift do. A kick never changes η, so every splitting conserves each spring's entropy exactly;
kicks and drifts are symplectic and equivariant under rigid motions, so linear and angular
momenta are conserved to round-off. Symmetric compositions of the symmetric CO2 keep all of this
and raise the order.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..errors import InputError
from ..integrators.base import Integrator, Stepper, register_integrator
from .schedule import CONDUCTION, WAVES, BuiltinFlow, StageTable, flow_slots, stage_table
from .stepper import SplittingStepper


@dataclass(frozen=True, repr=False)
class Splitting(Integrator):
    """An explicit splitting integrator.

    kicks: (S+1,) kick coefficients; drifts: (S,) drift coefficients (fractions of h).
    track_phi: False for NM2, which treats η as a parameter and does not integrate Φ.
    """

    name: str
    order: int
    kicks: tuple[float, ...]
    drifts: tuple[float, ...]
    track_phi: bool = True
    description: str = ""
    explicit: bool = True
    #: further sub-flows, ((position, SubFlow, coefficient), ...): position i ≤ S runs before
    #: kick i, S + 1 after the last kick (see :mod:`thermonet.explicit.schedule`)
    flows: tuple = ()
    #: (base, gammas) when this splitting is ``compose(base, gammas, ...)``: a composition with
    #: thermal waves composes the base with the waves' flow (:meth:`with_heat`)
    composition: tuple = ()

    def __post_init__(self):
        assert len(self.kicks) == len(self.drifts) + 1
        assert abs(sum(self.kicks) - 1.0) < 1e-13 and abs(sum(self.drifts) - 1.0) < 1e-13

    @property
    def table(self) -> StageTable:
        """The schedule every backend's kernels read (:func:`~thermonet.explicit.schedule.stage_table`)."""
        return stage_table(self.kicks, self.drifts, self.flows)

    @property
    def table_between_sweeps(self) -> StageTable:
        """The schedule without its conduction rows: what the CPU kernel runs between the
        conduction sweeps, which it places at the cycles' boundaries itself (and so keeps CO2's
        shared closing kick within a cycle)."""
        return stage_table(self.kicks, self.drifts, [f for f in self.flows if f[1] not in CONDUCTION])

    @property
    def subflows(self) -> tuple:
        """The distinct extra sub-flows, in the kernels' slot order."""
        return flow_slots(self.flows)

    def with_flow(self, flow, coefficient: float = 0.5, name: str | None = None) -> "Splitting":
        """``flow(c h) ∘ self(h) ∘ flow(c h)``: the symmetric splitting of this integrator and
        ``flow`` (c = ½: second order when self is symmetric and of order ≥ 2)."""
        last = len(self.drifts) + 1
        return replace(self, name=name or f"{self.name}+{flow.name}",
                       flows=self.flows + ((0, flow, coefficient), (last, flow, coefficient)),
                       description=f"{flow.name}({coefficient:g} h) around {self.name}")

    def with_heat(self, conduction: bool, waves: bool) -> "Splitting":
        """This splitting with heat flow (docs/theory.md §5–6): thermal waves as ``W(h/2) ∘ A ∘ W(h/2)``
        (a composition ``A = Π base(γ h)`` composes ``W ∘ base ∘ W`` instead, keeping its order),
        conduction as ``K(h/2) ∘ … ∘ K(h/2)`` around everything (second order at most: conduction
        cannot run backwards, so it is not composed)."""
        out = self
        if waves:
            if not self.track_phi:
                raise InputError(f"thermal waves need the thermal displacement Φ, which {self.name} does not "
                                 "integrate; use co2, co4 or co6")
            if self.composition:
                base, gammas = self.composition
                out = compose(base.with_heat(False, True), gammas, self.name, self.order, self.description)
            else:
                last = len(self.drifts) + 1
                out = replace(self, flows=self.flows + ((0, WAVES, 0.5), (last, WAVES, 0.5)))
        if conduction:
            last = len(out.drifts) + 1
            out = replace(out, flows=((0, CONDUCTION[0], 0.5),) + out.flows + ((last, CONDUCTION[1], 0.5),))
        effects = [e for e, on in (("conduction", conduction), ("thermal waves", waves)) if on]
        if not effects:
            return self
        # conduction caps the order at 2; waves keep it only in a composition of W ∘ base ∘ W
        order = 2 if conduction or (waves and not self.composition) else self.order
        return replace(out, name=f"{self.name}+{'+'.join(e.split()[-1] for e in effects)}", order=min(order, self.order),
                       description=f"{self.description}; with {' and '.join(effects)} (docs/theory.md §5–6)")

    @property
    def heat_rows(self) -> tuple[bool, bool]:
        """(conduction, thermal waves): which built-in heat-flow rows the schedule has."""
        codes = {f.code for _, f, _ in self.flows if isinstance(f, BuiltinFlow)}
        return CONDUCTION[0].code in codes, WAVES.code in codes

    @property
    def force_evaluations(self) -> int:
        """Force evaluations per step in a long run (the first and last kick share one)."""
        inner = sum(1 for k in self.kicks[1:-1] if k != 0.0)
        return inner + (1 if (self.kicks[0] != 0.0 or self.kicks[-1] != 0.0) else 0)

    def make_stepper(self, system, parallel: bool = False, backend: str = "cpu", **options) -> Stepper:
        """The CPU :class:`~thermonet.explicit.stepper.SplittingStepper`, or for ``backend="cuda"`` the GPU one
        (:class:`thermonet.explicit.cuda.stepper.CudaSplittingStepper`, state resident on the device)."""
        if backend == "cuda":
            from .cuda.stepper import CudaSplittingStepper

            return CudaSplittingStepper(self, system)
        return SplittingStepper(self, system, parallel)


def compose(base: Splitting, gammas, name: str, order: int, description: str) -> Splitting:
    """The composition ``base(γ_1 h) ∘ … ∘ base(γ_s h)``: adjacent kicks merged, or, when the base
    has sub-flows, kept apart (a zero drift between them) with the base's flows in every
    substep at γ times their coefficient."""
    if base.flows:
        return _compose_with_flows(base, gammas, name, order, description)
    kicks: list[float] = [0.0]
    drifts: list[float] = []
    for g in gammas:
        kicks[-1] += g * base.kicks[0]
        for k, d in zip(base.kicks[1:], base.drifts):
            drifts.append(g * d)
            kicks.append(g * k)
    return Splitting(name, order, tuple(kicks), tuple(drifts), base.track_phi, description,
                     composition=(base, tuple(gammas)))


def _compose_with_flows(base: Splitting, gammas, name: str, order: int, description: str) -> Splitting:
    if any(isinstance(f, BuiltinFlow) and f.code != WAVES.code for _, f, _ in base.flows):
        raise InputError(f"compose(): {base.name} has conduction rows, which cannot run backwards in time")
    kicks: list[float] = []
    drifts: list[float] = []
    flows: list = []
    per = len(base.kicks)
    for j, g in enumerate(gammas):
        if j:
            drifts.append(0.0)
        kicks.extend(g * k for k in base.kicks)
        drifts.extend(g * d for d in base.drifts)
        flows.extend((j * per + position, flow, g * c) for position, flow, c in base.flows)
    return Splitting(name, order, tuple(kicks), tuple(drifts), base.track_phi, description, flows=tuple(flows),
                     composition=(base, tuple(gammas)))


GTR0 = register_integrator(
    Splitting("gtr-0", 1, (0.0, 1.0), (1.0,), description="GTR-α with α = 0: drift then kick (symplectic Euler A), paper (51)")
)
GTR1 = register_integrator(
    Splitting("gtr-1", 1, (1.0, 0.0), (1.0,), description="GTR-α with α = 1: kick then drift (symplectic Euler B), paper (52)")
)
CO2 = register_integrator(
    Splitting("co2", 2, (0.5, 0.5), (1.0,), description="GTR-1 then GTR-0 half steps (F01), kick-drift-kick, paper (64)/(66)")
)
register_integrator(CO2, "f01")
F10 = register_integrator(
    Splitting("f10", 2, (0.0, 1.0, 0.0), (0.5, 0.5), description="GTR-0 then GTR-1 half steps, drift-kick-drift, paper (65)")
)
NM2 = register_integrator(
    Splitting(
        "nm2", 2, (0.5, 0.5), (1.0,), track_phi=False,
        description="velocity Verlet on H(x, p; η) with η a parameter (Newmark explicit), paper (41)-(44); no Φ",
    )
)

# Yoshida, "Construction of higher order symplectic integrators", Phys. Lett. A 150 (1990) 262-268:
# the triple jump, eq. (4.14)-(4.16).
_CBRT2 = 2.0 ** (1.0 / 3.0)
YOSHIDA4 = (1.0 / (2.0 - _CBRT2), -_CBRT2 / (2.0 - _CBRT2), 1.0 / (2.0 - _CBRT2))
CO4 = register_integrator(
    compose(CO2, YOSHIDA4, "co4", 4, "Yoshida's 4th-order triple jump of CO2 (Phys. Lett. A 150 (1990) 262)")
)

# Yoshida (1990), Table 1, solution A: w1, w2, w3; w0 = 1 − 2(w1 + w2 + w3); 7 substeps
# w3 w2 w1 w0 w1 w2 w3.
_W1, _W2, _W3 = -1.17767998417887, 0.235573213359357, 0.784513610477560
_W0 = 1.0 - 2.0 * (_W1 + _W2 + _W3)
YOSHIDA6A = (_W3, _W2, _W1, _W0, _W1, _W2, _W3)
CO6 = register_integrator(
    compose(CO2, YOSHIDA6A, "co6", 6, "Yoshida's 6th-order composition of CO2, solution A (Phys. Lett. A 150 (1990) 262)")
)



def palindrome(head, middle: float | None = None) -> tuple[float, ...]:
    """``head + (middle,) + reversed(head)`` (``middle`` omitted when None): a symmetric method's
    kicks or drifts from the first half, as the papers print them."""
    head = tuple(float(v) for v in head)
    return head + (() if middle is None else (float(middle),)) + head[::-1]


# Blanes & Moan, "Practical symplectic partitioned Runge-Kutta and Runge-Kutta-Nyström methods",
# J. Comput. Appl. Math. 142 (2002) 313-330, Table 3 (symmetric RKN methods, first stage a kick
# "b"). They need [B, [B, [B, A]]] = 0 for B the kick's Hamiltonian U(x, η) and A the drift's
# |p|²/2m: U does not depend on p or Φ and |p|²/2m not on x, η or Φ, so the brackets vanish as for
# any potential, with the Φ update riding along in every kick. The dependent (middle)
# coefficients are computed from the closure conditions Σ kicks = Σ drifts = 1, as in the paper.
#
# SRKN_6^b, order 4, 6 force evaluations per step: b1 a1 b2 a2 b3 a3 b4 a3 b3 a2 b2 a1 b1.
_BM4_B = (0.0829844064174052, 0.396309801498368, -0.0390563049223486)
_BM4_A = (0.245298957184271, 0.604872665711080)
BM4 = register_integrator(Splitting(
    "bm4", 4,
    palindrome(_BM4_B, 1.0 - 2.0 * sum(_BM4_B)),
    palindrome(_BM4_A + (0.5 - sum(_BM4_A),)),
    description="Blanes & Moan's optimized symmetric RKN splitting SRKN_6^b, order 4, 6 force evaluations "
                "(J. Comput. Appl. Math. 142 (2002) 313, Table 3)",
))

# SRKN_11^b, order 6, 11 force evaluations per step:
# b1 a1 b2 a2 b3 a3 b4 a4 b5 a5 b6 a6 b6 a5 b5 a4 b4 a3 b3 a2 b2 a1 b1.
_BM6_B = (0.0414649985182624, 0.198128671918067, -0.0400061921041533, 0.0752539843015807, -0.0115113874206879)
_BM6_A = (0.123229775946271, 0.290553797799558, -0.127049212625417, -0.246331761062075, 0.357208872795928)
BM6 = register_integrator(Splitting(
    "bm6", 6,
    palindrome(_BM6_B + (0.5 - sum(_BM6_B),)),
    palindrome(_BM6_A, 1.0 - 2.0 * sum(_BM6_A)),
    description="Blanes & Moan's optimized symmetric RKN splitting SRKN_11^b, order 6, 11 force evaluations "
                "(J. Comput. Appl. Math. 142 (2002) 313, Table 3)",
))


# SRKN_14^a, order 6, 14 force evaluations per step, drift first (the first stage is "a"):
# a1 b1 a2 b2 … a7 b7 a8 b7 a7 … b1 a1, with b7 = 1/2 − (b1 + … + b6), a8 = 1 − 2 (a1 + … + a7).
_BM6A_A = (0.0378593198406116, 0.102635633102435, -0.0258678882665587, 0.314241403071447,
           -0.130144459517415, 0.106417700369543, -0.00879424312851058)
_BM6A_B = (0.09171915262446165, 0.183983170005006, -0.05653436583288827, 0.004914688774712854,
           0.143761127168358, 0.328567693746804)
BM6A = register_integrator(Splitting(
    "bm6a", 6,
    palindrome((0.0,) + _BM6A_B + (0.5 - sum(_BM6A_B),)),
    palindrome(_BM6A_A, 1.0 - 2.0 * sum(_BM6A_A)),
    description="Blanes & Moan's optimized symmetric RKN splitting SRKN_14^a, order 6, 14 force evaluations, "
                "drift first (J. Comput. Appl. Math. 142 (2002) 313, Table 3)",
))


# Omelyan, Mryglod & Folk, "Symplectic analytically integrable decomposition algorithms:
# classification, derivation, and application to molecular dynamics, quantum and celestial
# mechanics simulations", Comput. Phys. Commun. 151 (2003) 272: the 4th-order,
# 5-force, minimum-norm "velocity version", eq. (63) with the parameters (71):
# B(ϑ) A(ρ) B(λ) A(θ) B(½ − (λ + ϑ)) A(1 − 2(θ + ρ)) B(½ − (λ + ϑ)) A(θ) B(λ) A(ρ) B(ϑ),
# B the kick and A the drift; the two middle coefficients follow from the sums.
_OMF4_RHO, _OMF4_THETA = 0.2539785108410595, -0.03230286765269967
_OMF4_VARTHETA, _OMF4_LAMBDA = 0.08398315262876693, 0.6822365335719091
OMF4 = register_integrator(Splitting(
    "omf4", 4,
    palindrome((_OMF4_VARTHETA, _OMF4_LAMBDA, 0.5 - (_OMF4_LAMBDA + _OMF4_VARTHETA))),
    palindrome((_OMF4_RHO, _OMF4_THETA), 1.0 - 2.0 * (_OMF4_THETA + _OMF4_RHO)),
    description="Omelyan, Mryglod & Folk's optimized symmetric splitting, order 4, 5 force evaluations, velocity "
                "version (Comput. Phys. Commun. 151 (2003) 272, eqs. (63), (71))",
))
