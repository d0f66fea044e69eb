"""Force evaluations to reach a position accuracy, for thermonet's explicit splittings and for
published kick/drift tables that thermonet does not register, over a dense range of step sizes.

    python benchmarks/evaluations_to_accuracy.py [--scenes chain,lattice] [--methods co4,bm4,...]
                                                 [--max-evaluations 1.2e5] [--orders]
    python benchmarks/evaluations_to_accuracy.py --quick   # a smoke run: see QUICK

Every method runs from t = 0 to ``--t-end`` (10) at the step sizes whose force evaluations per run
(evaluations per step × steps) go from ``--start-evaluations`` (200) to ``--max-evaluations`` in
ratios of 2^(1/8); the error is the paper's norm (root of the sum of squares over every component)
of the positions at t_end against DOP853 at rtol = atol = ``--reference-rtol`` (the cost study's
reference, checked against BM6 at h = 1.25e-3). The errors are deterministic (no timing), so one
run per step size. "Evaluations to reach ε": the number of evaluations beyond which every run
of the sweep has error ≤ ε, interpolated log-log between the last run above ε and the next one
(on the chain the error is not monotone in h at loose accuracies, so the first run below ε can
come earlier: on this grid by up to a quarter of the evaluations for some unregistered tables at
1e-2–1e-3, by 12 % for BM6 at 1e-4, and not at all for the other registered methods).

Prints, per scene, the evaluations to reach 1e-2 … 1e-8 for every method, and the ratios to CO4
and CO6 (> 1: fewer evaluations than the triple jump). ``--orders`` first prints each table's
measured order: log-log slopes of the position error at t = 1 on the chain against DOP853 at
1e-13 over h = 0.1·2⁻ⁱ (the local slopes, and the slope fitted over the four smallest step sizes
whose error is above 1e-12, the reference's floor being ≈ 5e-14).

The unregistered tables (``CANDIDATES``) are typed from the papers cited beside them (the
dependent coefficients computed from the sums, as the papers do); each one's order is measured
by ``--orders``. Tables that are not symmetric, or whose first kick is zero, share the
first/last force evaluation as the registered ones do (``Splitting.force_evaluations``).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import thermonet as tn  # noqa: E402
from thermonet.explicit.splitting import CO2, F10, Splitting, compose, palindrome  # noqa: E402
from thermonet.studies import reference_solution  # noqa: E402
from thermonet.studies.scenes import make_simulation  # noqa: E402
from thermonet.studies.snapshot import Snapshot  # noqa: E402

ACCURACIES = [10.0**-k for k in range(2, 9)]
REGISTERED = ["co2", "co4", "co6", "bm4", "omf4", "bm6", "bm6a"]


def sequence(name: str, order: int, ops, citation: str) -> Splitting:
    """A splitting from its operators in the order applied: ("K", c) a kick of c·h, ("D", c) a
    drift of c·h; adjacent operators of one kind merge, zero drifts drop."""
    kicks, drifts = [0.0], []
    for kind, c in ops:
        if kind == "K":
            kicks[-1] += c
        elif c != 0.0:
            if len(drifts) == len(kicks):  # the last operator was a drift
                drifts[-1] += c
            else:
                drifts.append(c)
                kicks.append(0.0)
    if len(kicks) == len(drifts):
        kicks.append(0.0)
    return Splitting(name, order, tuple(kicks), tuple(drifts), description=citation)


def alternate(first: str, a, b):
    """``first``(a₁) other(b₁) first(a₂) other(b₂) …"""
    other = "D" if first == "K" else "K"
    ops = []
    for i in range(max(len(a), len(b))):
        ops += [(first, a[i])] if i < len(a) else []
        ops += [(other, b[i])] if i < len(b) else []
    return ops


def swap(ops):
    """The same coefficients with kicks and drifts exchanged."""
    return [("D" if k == "K" else "K", c) for k, c in ops]


def composition(name, order, gammas, citation, base=CO2):
    return compose(base, tuple(gammas), name, order, citation)


def _candidates() -> dict[str, Splitting]:
    c: dict[str, Splitting] = {}

    def add(s):
        c[s.name] = s

    # -- order 4 --------------------------------------------------------------------------------
    p = 1.0 / (4.0 - 4.0 ** (1.0 / 3.0))
    add(composition("suzuki4", 4, (p, p, 1 - 4 * p, p, p),
                    "Suzuki's fractal composition of CO2, 5 stages (Phys. Lett. A 146 (1990) 319)"))
    ss5 = (0.28, 0.6254664284676700450, -0.8109328569353400900)
    add(composition("mcl-ss5", 4, palindrome(ss5[:2], ss5[2]),
                    "McLachlan's symmetric composition s = 5 of CO2 (SIAM J. Sci. Comput. 16 (1995) 151)"))
    a = [0.40518861839525227722, -0.28714404081652408900]
    b = [-3.0 / 73.0, 17.0 / 59.0]
    a6 = palindrome(a + [0.5 - sum(a)])
    b5 = palindrome(b, 1.0 - 2.0 * sum(b))
    add(sequence("mcl-sb3a5", 4, alternate("D", a6, b5),
                 "McLachlan's RKN method SB3A, 5 forces, drift first (SIAM J. Sci. Comput. 16 (1995) 151)"))
    z = math.sqrt(7.0 / 8.0) / 3.0
    add(sequence("mcl-sb3a4", 4, alternate("D", palindrome([0.5 - z, z - 1.0 / 3.0], 2.0 / 3.0),
                                           palindrome([1.0, -0.5])),
                 "McLachlan's RKN method SB3A, 4 forces, drift first (SIAM J. Sci. Comput. 16 (1995) 151)"))
    s19 = math.sqrt(19.0)
    k5 = [(14 - s19) / 108, (20 - 7 * s19) / 108]
    k5 = palindrome(k5 + [0.5 - sum(k5)])
    d5 = (0.4, -0.1, 0.4, -0.1, 0.4)
    add(sequence("mcl-s5k", 4, alternate("K", k5, d5),
                 "McLachlan's symmetric splitting S5, kick first (SIAM J. Sci. Comput. 16 (1995) 151)"))
    add(sequence("mcl-s5d", 4, swap(alternate("K", k5, d5)),
                 "McLachlan's symmetric splitting S5, drift first (SIAM J. Sci. Comput. 16 (1995) 151)"))
    s471 = math.sqrt(471.0)
    k4 = [(642 + s471) / 3924, 121 * (12 - s471) / 3924]
    s4 = alternate("K", palindrome(k4, 1 - 2 * sum(k4)), palindrome([6.0 / 11.0, 0.5 - 6.0 / 11.0]))
    add(sequence("mcl-s4k", 4, s4,
                 "McLachlan's symmetric splitting S4, kick first (SIAM J. Sci. Comput. 16 (1995) 151)"))
    add(sequence("mcl-s4d", 4, swap(s4),
                 "McLachlan's symmetric splitting S4, drift first (SIAM J. Sci. Comput. 16 (1995) 151)"))
    pa = [0.0792036964311957, 0.353172906049774, -0.0420650803577195]
    pb = [0.209515106613362, -0.143851773179818]
    a7 = palindrome(pa, 1 - 2 * sum(pa))
    b6 = palindrome(pb + [0.5 - sum(pb)])
    add(sequence("bm-prk6d", 4, alternate("D", a7, b6),
                 "Blanes & Moan's PRK_6 (S6), drift first (J. Comput. Appl. Math. 142 (2002) 313, Table 2)"))
    add(sequence("bm-prk6k", 4, alternate("K", a7, b6),
                 "Blanes & Moan's PRK_6 (S6), kick first (J. Comput. Appl. Math. 142 (2002) 313, Table 2)"))
    pefrl = (0.1786178958448091, -0.2123418310626054, -0.06626458266981849)  # ξ, λ, χ
    vefrl = (0.1644986515575760, -0.02094333910398989, 1.235692651138917)
    efrl = (0.1720865590295143, -0.09156203075515678, -0.1616217622107222)
    for name, (xi, lam, chi), first in (("pefrl", pefrl, "D"), ("vefrl", vefrl, "K"), ("efrl-d", efrl, "D"),
                                        ("efrl-k", efrl, "K")):
        outer = palindrome([xi, chi], 1 - 2 * (chi + xi))
        inner = palindrome([(1 - 2 * lam) / 2, lam])
        add(sequence(name, 4, alternate(first, outer, inner),
                     f"Omelyan, Mryglod & Folk's {name.upper()} (Comput. Phys. Commun. 146 (2002) 188)"))
    rho, theta, vt, lam = 0.2750081212332419, -0.1347950099106792, -0.08442961950707149, 0.3549000571574260
    add(sequence("omf4p", 4, alternate("D", palindrome([rho, theta, 0.5 - (theta + rho)]),
                                       palindrome([vt, lam], 1 - 2 * (lam + vt))),
                 "Omelyan, Mryglod & Folk's 4th order, 5 forces, position version, eqs. (72), (80) "
                 "(Comput. Phys. Commun. 151 (2003) 272)"))
    ma4a = [0.515352837431122936, -0.085782019412973646, 0.441583023616466524, 0.128846158365384185]
    ma4b = [0.134496199277431089, -0.224819803079420806, 0.756320000515668291, 0.334003603286321425]
    add(sequence("mcat4", 4, alternate("K", ma4b, ma4a),
                 "McLachlan & Atela's optimal 4th order, 4 stages, not symmetric (Nonlinearity 5 (1992) 541)"))
    csa = [0.205177661542290, 0.403021281604210, -0.12092087633891, 0.512721933192410, 0.0]
    csb = [0.061758858135626, 0.33897802655364, 0.61479130717558, -0.14054801465937, 0.12501982279453]
    add(sequence("calvo-sanz4", 4, alternate("K", csb, csa),
                 "Calvo & Sanz-Serna's 4th order, not symmetric (SIAM J. Sci. Comput. 14 (1993) 936)"))
    # -- order 5 (not symmetric) --------------------------------------------------------------------
    ma5a = [0.339839625839110000, -0.088601336903027329, 0.5858564768259621188, -0.603039356536491888,
            0.3235807965546976394, 0.4423637942197494587]
    ma5b = [0.1193900292875672758, 0.6989273703824752308, -0.1713123582716007754, 0.4012695022513534480,
            0.0107050818482359840, -0.0589796254980311632]
    add(sequence("mcat5", 5, alternate("K", ma5b, ma5a),
                 "McLachlan & Atela's optimal 5th order, 6 stages (Nonlinearity 5 (1992) 541)"))
    # -- order 6 --------------------------------------------------------------------------------
    kl6 = (0.39216144400731413927925056, 0.33259913678935943859974864, -0.70624617255763935980996482,
           0.08221359629355080023149045, 0.79854399093482996339895035)
    add(composition("kahan-li6", 6, palindrome(kl6[:4], kl6[4]),
                    "Kahan & Li's composition s = 9 of CO2 (Math. Comput. 66 (1997) 1089)"))
    ss9 = [0.1867, 0.55549702371247839916, 0.12946694891347535806, -0.84326562338773460855]
    add(composition("mcl-ss9", 6, palindrome(ss9, 1 - 2 * sum(ss9)),
                    "McLachlan's symmetric composition s = 9 of CO2 (SIAM J. Sci. Comput. 16 (1995) 151)"))
    add(composition("mcl-ss9-dkd", 6, palindrome(ss9, 1 - 2 * sum(ss9)),
                    "McLachlan's composition s = 9 of drift-kick-drift (SIAM J. Sci. Comput. 16 (1995) 151)",
                    base=F10))
    ss11 = [0.21375583945878254555518066964857, 0.18329381407425713911385974425217,
            0.17692819473098943794898811709929, -0.44329082681170215849622829626258,
            0.11728560432865935385403585669136]
    add(composition("sofspa6-11", 6, palindrome(ss11, 1 - 2 * sum(ss11)),
                    "Sofroniou & Spaletta's composition s = 11 of CO2 (Optim. Methods Softw. 20 (2005) 597)"))
    ss13 = [0.13861930854051695245808013042625, 0.13346562851074760407046858832209,
            0.13070531011449225190542755785015, 0.12961893756907034772505366537091,
            -0.35000324893920896516170830911323, 0.11805530653002387170273438954049]
    add(composition("sofspa6-13", 6, palindrome(ss13, 1 - 2 * sum(ss13)),
                    "Sofroniou & Spaletta's composition s = 13 of CO2 (Optim. Methods Softw. 20 (2005) 597)"))
    s10a = [0.050262764400392200, 0.41351430042834400, 0.045079889794397700, -0.18805485381956900,
            0.54196067845078000]
    s10b = [0.14881644790104200, -0.13238586576778400, 0.067307604692185000, 0.43266640257817500]
    add(sequence("bm-s10", 6, alternate("D", palindrome(s10a, 1 - 2 * sum(s10a)),
                                        palindrome(s10b + [0.5 - sum(s10b)])),
                 "Blanes & Moan's S10, 10 forces, drift first (J. Comput. Appl. Math. 142 (2002) 313, Table 2)"))
    osa = [-1.0130879789171747298, 1.1874295737325427070, -0.018335852096460590340, 0.34399425728109261313]
    osb = [0.00016600692650009894, -0.37962421426377360608, 0.68913741185181063674]
    add(sequence("okunbor-skeel6", 6, alternate("D", palindrome(osa), palindrome(osb, 1 - 2 * sum(osb))),
                 "Okunbor & Skeel's canonical RKN method of order 6, 7 forces (J. Comput. Appl. Math. 51 (1994) 375)"))
    oa = [0.2465881872786138, 0.6047073875057809, -0.4009869039788007]
    ob = [0.08333333333333333, 0.3977675859548440, -0.03933369314462574]
    add(sequence("omf6", 6, alternate("K", palindrome(ob + [0.5 - sum(ob)]), palindrome(oa, 1 - 2 * sum(oa))),
                 "Omelyan, Mryglod & Folk's 6th order, 7 forces, velocity version, eq. (83) "
                 "(Comput. Phys. Commun. 151 (2003) 272)"))
    # -- order 8 --------------------------------------------------------------------------------
    kl8 = (0.13020248308889008087881763, 0.56116298177510838456196441, -0.38947496264484728640807860,
           0.15884190655515560089621075, -0.39590389413323757733623154, 0.18453964097831570709183254,
           0.25837438768632204729397911, 0.29501172360931029887096624)
    add(composition("kahan-li8", 8, palindrome(kl8, 1 - 2 * sum(kl8)),
                    "Kahan & Li's composition s = 17 of CO2 (Math. Comput. 66 (1997) 1089)"))
    m8 = (0.74167036435061295344822780, -0.40910082580003159399730010, 0.19075471029623837995387626,
          -0.57386247111608226665638773, 0.29906418130365592384446354, 0.33462491824529818378495798,
          0.31529309239676659663205666)
    add(composition("mcl-ss15", 8, palindrome(m8, 1 - 2 * sum(m8)),
                    "McLachlan's symmetric composition s = 15 of CO2 (SIAM J. Sci. Comput. 16 (1995) 151)"))
    ss21 = [0.10647728984550031823931967854896, 0.10837408645835726397433410591546,
            0.35337821052654342419534541324080, -0.23341414023165082198780281128319,
            -0.24445266791528841269462171413216, 0.11317848435755633314700952515599,
            0.11892905625000350062692972283951, 0.12603912321825988140305670268365,
            0.12581718736176041804392391641587, 0.11699135019217642180722881433533]
    add(composition("sofspa8-21", 8, palindrome(ss21, 1 - 2 * sum(ss21)),
                    "Sofroniou & Spaletta's composition s = 21 of CO2 (Optim. Methods Softw. 20 (2005) 597)"))
    b19a = [0.337548675291317241942440116575, -0.223647977575409990331768222380, 0.168949714872223740906385138015,
            0.171179938816205886154783136334, -0.349765168067292877221144631312, 0.523808861006312397712070357524,
            -0.194208871063049124066394765282, -0.323496751337931087309823477561, 0.322817287614899749216601693799]
    b19b = [0.036132460472136313416730168194, 0.012697863961074113381675193011, 0.201318391240629276109068041836,
            0.135683350134504233201330671671, -0.0579071833999963041504740663015, -0.0772509501792649549463874931821,
            -0.00264758266409925952822161203471, -0.0329844384945603065320797537355, 0.0476781560950366927530646289755]
    add(sequence("bce-b19", 8, alternate("K", palindrome(b19b + [0.5 - sum(b19b)]),
                                         palindrome(b19a, 1 - 2 * sum(b19a))),
                 "Blanes, Casas & Escorihuela-Tomàs' RKN method B19, order 8 (arXiv:2202.01541, Table 5)"))
    a18a = [0.0866003822712445920135805954462, -0.0231572735424388070228714693753, 0.191410576083774088999564416369,
            0.378895558692931579545387584925, -0.0467359566364556111599485526051, -0.156198111997810415438979605642,
            0.156025836895094823718831871041, 0.252844012473796333586850465807, -0.640644212172254239866860564270]
    a18b = [-0.08, 0.209460550048243262121199483001, 0.274887805875735483503233064415,
            -0.224214208870409561366168655624, 0.347657740563761656321390026010, -0.168783183866211679175007668385,
            0.144209344805460873709120777707, 0.0116851121360265483381405054244]
    add(sequence("bce-a18", 8, alternate("D", palindrome(a18a, 1 - 2 * sum(a18a)),
                                         palindrome(a18b + [0.5 - sum(a18b)])),
                 "Blanes, Casas & Escorihuela-Tomàs' RKN method A18, order 8 (arXiv:2202.01541, Table 4)"))
    return c


CANDIDATES = _candidates()


def method(name: str) -> Splitting:
    return CANDIDATES[name] if name in CANDIDATES else tn.get_integrator(name)


def sweep(scene, integrator, reference, t_end, start, stop, per_doubling):
    """[(steps, evaluations, error)] over the evaluation grid; a failed or non-finite run is inf."""
    s = integrator.force_evaluations
    rows, k = [], 0
    while True:
        steps = max(1, round(start * 2.0 ** (k / per_doubling) / s))
        k += 1
        if rows and steps <= rows[-1][0]:
            continue
        if steps * s > stop:
            return rows
        sim = make_simulation(scene, integrator, t_end / steps, threads=1, stability_guard="off",
                              energy_tolerance=None)
        try:
            with np.errstate(all="ignore"):
                sim.run(steps=steps, diagnostics_every=steps)
            err = Snapshot.of(sim).errors(reference.snapshot)["position"]
        except tn.errors.ThermonetError:
            err = math.inf
        rows.append((steps, steps * s, err if math.isfinite(err) else math.inf))


def evaluations_to_reach(rows, acc):
    """Evaluations beyond which every run has error ≤ acc (log-log interpolated); None if the
    finest run does not reach it."""
    if not rows or rows[-1][2] > acc:
        return None
    above = [i for i, r in enumerate(rows) if r[2] > acc]
    if not above:
        return float(rows[0][1])
    (_, e0, v0), (_, e1, v1) = rows[above[-1]], rows[above[-1] + 1]
    if not math.isfinite(v0):
        return float(e1)
    w = (math.log(acc) - math.log(v0)) / (math.log(v1) - math.log(v0))
    return math.exp(math.log(e0) + w * (math.log(e1) - math.log(e0)))


def measured_orders(names) -> dict:
    """Print each method's measured order; returns name -> (declared order, local slopes, fitted
    slope)."""
    from thermonet import reference as ref
    from thermonet.paper import CHAIN_MOMENTA, CHAIN_PARAMETERS, CHAIN_TEMPERATURES

    net = tn.chain()
    rnet = ref.ReferenceNet.build(net, "hencky", CHAIN_PARAMETERS)
    eta = rnet.entropies(net.positions, CHAIN_TEMPERATURES)
    start = ref.ReferenceState(net.positions.copy(), CHAIN_MOMENTA.copy(), np.zeros(3), eta)
    x_ref = ref.hamilton_solution(rnet, start, 1.0, rtol=1e-13, atol=1e-13).x
    print("\n### Measured orders (chain, t = 1, max position error against DOP853 at 1e-13)\n")
    print("| method | declared | local slopes, h = 0.1·2⁻ⁱ, i = 0…8 "
          "| fitted (4 smallest h with error > 1e-12) |")
    print("|---|---|---|---|")
    orders = {}
    for name in names:
        integrator = method(name)
        h = np.array([0.1 * 2.0**-i for i in range(9)])
        err = []
        for hi in h:
            sim = tn.chain_simulation(integrator, h=hi, stability_guard="off", energy_tolerance=None)
            with np.errstate(all="ignore"):
                sim.run(t_end=1.0, diagnostics_every=10**9)
            err.append(np.abs(sim.state.positions - x_ref).max())
        err = np.array(err)
        local = np.log2(err[:-1] / err[1:])
        ok = np.flatnonzero(err > 1e-12)[-4:]
        fit = np.polyfit(np.log(h[ok]), np.log(err[ok]), 1)[0] if len(ok) >= 3 else float("nan")
        print(f"| {name} | {integrator.order} | {' '.join(f'{s:.2f}' for s in local)} | {fit:.2f} |", flush=True)
        orders[name] = (integrator.order, local, fit)
    return orders


def fmt(v):
    return "–" if v is None else f"{v:.0f}"


def ratio(a, b):
    return "–" if a is None or b is None else f"{a / b:.2f}"


#: --quick: three registered methods and three unregistered tables (a composition of CO2, a
#: symmetric kick/drift sequence, one not symmetric) on the chain to t = 1, 200–2000 evaluations,
#: 2 per doubling, with their measured orders
QUICK = dict(methods="co4,co6,bm4,suzuki4,mcl-s4k,mcat4", t_end=1.0, max_evaluations=2000.0, per_doubling=2,
             orders=True, scenes="chain")


def main(argv=None) -> dict:
    """Run the benchmark (``argv``: its command line); returns {"orders": name -> (declared,
    local slopes, fitted slope) (with --orders), "reach": scene -> name -> evaluations to reach
    each of ACCURACIES (None: not reached), "sweeps": scene -> name -> [(steps, evaluations,
    error)]}."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="chain")
    ap.add_argument("--methods", default=",".join(REGISTERED + list(CANDIDATES)),
                    help="registered names or the names in CANDIDATES (default: all)")
    ap.add_argument("--t-end", type=float, default=10.0)
    ap.add_argument("--start-evaluations", type=float, default=200.0)
    ap.add_argument("--max-evaluations", type=float, default=1.2e5)
    ap.add_argument("--per-doubling", type=int, default=8)
    ap.add_argument("--reference-rtol", type=float, default=3e-14)
    ap.add_argument("--orders", action="store_true", help="first print each method's measured order on the chain")
    ap.add_argument("--quick", action="store_true", help="a smoke run (QUICK: 6 methods, the chain to t = 1, "
                    "up to 2000 evaluations, --orders)")
    args = ap.parse_args(argv)
    if args.quick:
        vars(args).update(QUICK)
    names = [n.strip() for n in args.methods.split(",") if n.strip()]
    for n in ("co4", "co6"):
        if n not in names:
            names.insert(0, n)
    warnings.simplefilter("ignore")
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; evaluations are "
          f"counted, not timed")
    result = {"orders": measured_orders(names) if args.orders else {}, "reach": {}, "sweeps": {}}
    for scene in args.scenes.split(","):
        started = time.perf_counter()
        reference = reference_solution(scene, args.t_end, args.reference_rtol, check=("bm6", 0.04 / 32))
        print(f"\n### {scene}: force evaluations to reach a position error at t = {args.t_end:g}\n")
        print(f"reference: {reference.description}; runs from {args.start_evaluations:g} to "
              f"{args.max_evaluations:g} evaluations, {args.per_doubling} per doubling\n")
        reach, sweeps = result["reach"].setdefault(scene, {}), result["sweeps"].setdefault(scene, {})
        for name in names:
            integrator = method(name)
            rows = sweep(scene, integrator, reference, args.t_end, args.start_evaluations, args.max_evaluations,
                         args.per_doubling)
            reach[name] = [evaluations_to_reach(rows, acc) for acc in ACCURACIES]
            sweeps[name] = rows
        head = " | ".join(f"{a:.0e}" for a in ACCURACIES)
        print(f"| method | order | evaluations per step | {head} |")
        print("|---|---|---|" + "---|" * len(ACCURACIES))
        for name in names:
            integrator = method(name)
            print(f"| {name} | {integrator.order} | {integrator.force_evaluations} | "
                  + " | ".join(fmt(v) for v in reach[name]) + " |")
        print(f"\n{scene}: CO4 / method and CO6 / method at each accuracy (> 1: fewer evaluations)\n")
        cols = [f"CO4/· {a:.0e}" for a in ACCURACIES] + [f"CO6/· {a:.0e}" for a in ACCURACIES]
        print("| method | " + " | ".join(cols) + " |")
        print("|---|" + "---|" * (2 * len(ACCURACIES)))
        for name in names:
            cells = [ratio(a, b) for a, b in zip(reach["co4"], reach[name])]
            cells += [ratio(a, b) for a, b in zip(reach["co6"], reach[name])]
            print(f"| {name} | " + " | ".join(cells) + " |")
        print(f"\n({scene}: {time.perf_counter() - started:.0f} s)")
    return result


if __name__ == "__main__":
    main()
