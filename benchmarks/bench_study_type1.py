"""Type-I error of ``study analyze``'s contrasts when the stimuli vary (a review, finding 6).

Null studies (no condition effect) are drawn from ``laughlab.study.power.simulate`` over 4 conditions x
``--items`` audio items (every participant rates every video, the Latin-square orders of
``experiment=stimuli``), each fitted with ``analyze.fit_model`` and tested with ``analyze.contrasts``
(Wald z, Holm over the 6 pairs).  Printed: the share of studies in which one contrast (smile_only -
laugh_energy) has p < .05 and Holm's p < .05, and the familywise share (any contrast, Holm's p < .05),
each with a 95 % Wilson interval; nominal 0.05 for the first and the last.

The review measured, with 24 participants, 4 items and a stimulus variance of 0.5 (participant 0.64,
residual 1.44): familywise 38/400 = 0.095.  On 2026-11-29, 12 participants, 200 studies each, seed 11: 4 items
at the default stimulus variance 0.09: 0.065; 2 items: 0.075; 2 items at 0.5: 0.185.  ``study analyze`` warns in
its README for every question with fewer than 10 stimuli per condition (``analyze.few_stimuli_note``).

Run: ``python benchmarks/bench_study_type1.py --participants 24 --sims 200 --var-stimulus 0.5 --seed 1``
(about 3 minutes on 2 busy cores).
"""
from __future__ import annotations

import argparse
import warnings


def main() -> None:
    import numpy as np
    from laughlab_experiments.stimuli import participant_trials

    from laughlab.study.analyze import contrasts, fit_model
    from laughlab.study.power import DEFAULT_VAR, simulate, wilson

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=24)
    ap.add_argument("--items", type=int, default=4, help="audio items, so stimuli per condition (4)")
    ap.add_argument("--sims", type=int, default=200)
    ap.add_argument("--var-stimulus", type=float, default=0.5)
    ap.add_argument("--seed", type=int, default=1)
    ns = ap.parse_args()
    warnings.simplefilter("ignore")
    conds = ["smile_only", "face_breathing", "laugh_energy", "laugh_concat"]
    items = [f"i{k}" for k in range(1, ns.items + 1)]
    var = {**DEFAULT_VAR, "stimulus": ns.var_stimulus}
    rng = np.random.default_rng(ns.seed)
    trials = participant_trials(conds, items, ns.participants, "all")
    raw = holm = family = 0
    for _ in range(ns.sims):
        fit, ref, _ = fit_model(simulate(trials, {}, var, 4.0, rng, (1, 7)), conds)
        c = contrasts(fit, ref, conds)
        r = c[(c.a == "smile_only") & (c.b == "laugh_energy")].iloc[0]
        raw += r.p < .05
        holm += r.p_holm < .05
        family += (c.p_holm < .05).any()
    print(f"{ns.participants} participants, {ns.items} stimuli per condition, stimulus variance {ns.var_stimulus:g}, "
          f"{ns.sims} null studies (seed {ns.seed}):")
    for name, k in (("one contrast, p < .05", raw), ("one contrast, Holm p < .05", holm),
                    ("familywise, any Holm p < .05", family)):
        lo, hi = wilson(int(k), ns.sims)
        print(f"  {name}: {k}/{ns.sims} = {k / ns.sims:.3f} (95 % CI {lo:.3f}-{hi:.3f})")


if __name__ == "__main__":
    main()
