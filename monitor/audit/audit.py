"""The model audit: what the paper's model gets wrong in a record, and which named extension fixes it.

``audit(samples, config) -> AuditResult`` is pure. The record is split in time: the first
``train_fraction`` fits, the rest scores.

1. Identify the nominal model on the training part (``monitor.audit.residuals``: force,
   rest, chamber and valve blocks; batch least squares and a valve output-error fit).
2. For every candidate of the library (``monitor.audit.candidates``), search its nonlinear
   parameter on the training part (best training fit), then score it on the held-out part:

       score = sum_g ln(V_g,nominal / V_g,extended) - penalty * k

   with V_g the held-out residual variance of block g (force, rest, chamber, valve; the
   regressor-noise share removed, see ``monitor.audit.residuals.Fit.mse``) and k the
   parameters the extension adds, less what the same extension at the same value scores on
   the nominal model's twin (``monitor.audit.equations._twin``: the nominal free run with the
   record's noise level, which holds no effect). A term earns its place when its score exceeds
   ``threshold`` AND it also improves the training part (sum of training log ratios above
   ``TRAIN_SHARE`` of the threshold): an improvement that appears on one part only is noise.
   The score is scale-free (a relative variance reduction, 0.1 = about 10 %); we do not use
   N-weighted likelihoods because the filtered equations' residuals are strongly correlated
   and their effective sample size is not known well enough. The threshold is calibrated on
   simulated clean records (the largest clean-record score we saw in 40 seeds was about 0.10).
3. Re-simulate the nominal and each extended model in free run from the measured ug
   (``monitor.audit.freerun``) and measure the held-out error per channel (the gain). For a
   searched scalar (dead band, supply resistance) the simulated value is polished among
   ``POLISH`` multiples by the free-run error on the training part only.

4. When nothing earns its place, a Stribeck hump may still be named from its free run
   (``monitor.audit.hump``): fitted to the training part's free-run error, it must simulate the
   held-out part better than the nominal model with its Coulomb and viscous friction refitted
   the same way (rule 5 of ``monitor.audit.decide``).

The cause is the best-scoring candidate if it earns its place, else "none". When a
runner-up that also earns its place scores more than ``margin`` times the winner, or the
winner has a caveat (Stribeck friction: nearly collinear with Coulomb plus viscous friction
at these speeds) and barely earns its place, ``confident`` is False and ``note`` says why.
"""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import numpy as np

from hydromon.contract import RigConfig
from plant_sim.params import Effects

from .candidates import LIBRARY
from .equations import TWIN_FIT, _Equations, _floors, _log_ratio, _mse_split, _twin
from .freerun import channel_scores, free_run, free_run_gain, mean_nrmse, output_error_fit
from .residuals import BLOCKS, merge_specs, nominal_params
from .verdict import EQUATION_OF, POSITIVE_AUDIT, impossible_params  # noqa: F401  (re-exported)
from .decide import decide
from .hump import hump_evidence
from .probe import probe_fits
from .reach import stribeck_reach
from .result import AuditOptions, AuditResult, CandidateResult
from .signals import require_length
from ..outlier_gate import gated
from .auditable import require_auditable

__all__ = ["audit", "AuditResult", "CandidateResult", "AuditOptions"]

POLISH = (0.4, 0.6, 0.8, 1.25)  # factors on a refined searched value tried in the free-run polish
def _output_error(cand, params, effect, s, cfg, split, fallback, v0):
    """The candidate's free-run variables refined on the training part's free-run error from
    each of its starts; returns the best (params, effect)."""
    starts, to_model = cand.free_run_variables(params, effect)
    return output_error_fit(starts, to_model, s, cfg, slice(0, split), v0, fallback)[:2]


def _unfit_words(e: ValueError) -> str:
    """Why a candidate could not be fitted, for a person."""
    if isinstance(e, np.linalg.LinAlgError):
        # a column of the extension that is a combination of the model's on the rows at hand:
        # a constant force where every sliding row of the force equation runs one way is
        # Coulomb friction there
        return ("its extended equations are singular on this record's rows: what it adds is a combination of "
                "the nominal model's terms there")
    return str(e)


def audit(samples: np.ndarray, config: RigConfig | None = None, options: AuditOptions | None = None,
          library=LIBRARY, progress=None) -> AuditResult:
    """Audit one record.

    Parameters
    ----------
    samples : array (N, 5)
        ug [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m] at the config's sample rate.
    config : RigConfig
        The rig's constants (default: the paper's).
    options : AuditOptions
    library : sequence of Candidate
        The named extensions to rank (default: all seven).
    progress : callable or None
        Called as ``progress(done, total, name)`` once the nominal model is fitted (``done``
        0, ``name`` ``"nominal"``) and after each candidate (``done`` of ``total`` tried,
        ``name`` the candidate's): a long record takes minutes.
    """
    cfg = config or RigConfig()
    opt = options or AuditOptions()
    s = np.asarray(samples, dtype=float)
    replaced = np.zeros(4)
    if s.ndim == 2 and s.shape[1] == 5 and np.all(np.isfinite(s)):  # else ``signals`` says what is wrong
        require_length(s)  # before any check of what the samples hold
        # a lone glitch (or a pair on x1, x3, x4) is replaced by its neighbours as the live monitor
        # replaces it: a one-sample spike of a pressure 10 times its usual step reads as entrained
        # air; a dead channel, a dropout longer than the gate mends or a held rig is refused
        s, replaced = gated(s)
        require_auditable(s, cfg, int(opt.train_fraction * len(s)))
    eq = _Equations(s, cfg, opt.train_fraction)
    sig, split, cache, nominal, p_nom, theta0 = eq.sig, eq.split, eq.cache, eq.nominal, eq.p_nom, eq.theta0
    floors, nom_tr, nom_te = eq.floors, eq.nom_tr, eq.nom_te
    test = slice(split, sig.n)
    measured = s[:, 1:]
    # a nominal fit with impossible estimates proves nothing by equation error alone: an
    # extension is named then only when its free run also simulates the held-out part better
    impossible = impossible_params(p_nom)
    # every candidate that scores above the threshold is re-simulated, free run on or off: a model
    # whose free run diverges explains nothing (clean stress-noise records were named for a
    # residual variance that only the extension's larger predicted noise share had lowered)
    run = free_run(s, cfg, p_nom, v0=float(sig.vl[0]))
    sim_nom, nominal_diverged = run.measured, run.diverged
    fr_nom = channel_scores(measured, sim_nom, test)

    def simulate(params, effect):  # an extended model's free run; invalid parameters take the nominal ones
        return free_run(s, cfg, params, Effects(**effect), v0=float(sig.vl[0]), fallback=p_nom)

    fit_at = eq.fit_at
    @functools.cache  # built when first asked, once per audit
    def twin_equations():
        """The nominal model's twin's equations (``_twin``), or None: the nominal free run
        diverged or strays from the record (``TWIN_FIT``), or the twin's equations cannot be
        fitted (a twin that stays at rest, say)."""
        if nominal_diverged or not mean_nrmse(fr_nom) <= TWIN_FIT:
            return None
        try:
            return _Equations(_twin(s, sim_nom, sig.sigma), cfg, opt.train_fraction)
        except (ValueError, np.linalg.LinAlgError):
            return None

    def twin_score(cand, value) -> float:
        """What ``cand`` at ``value`` scores on the nominal model's twin, at least 0 (0: no
        twin, or the twin's rows cannot fit the candidate)."""
        tw = twin_equations()
        if tw is None:
            return 0.0
        try:
            (physical, _), _, f = tw.fit_at(cand, value)
        except (ValueError, np.linalg.LinAlgError):
            return 0.0
        return max(tw.score(cand, physical, f, opt)[0], 0.0)

    if progress is not None:
        progress(0, len(library), "nominal")
    results, fits, unfitted = [], {}, {}
    for done, cand in enumerate(library, 1):
        if progress is not None and done > 1:
            progress(done - 1, len(library), library[done - 2].name)
        best, why = None, ""
        grid = cand.grid(sig)
        for value in grid:
            try:
                trial = fit_at(cand, value)
            except ValueError as e:  # e.g. a spool stop so low that no valve row is free of it
                why = _unfit_words(e)
                continue
            if best is None or trial[0] > best[0]:
                best = trial
        if best is not None and cand.refine and len(grid) > 1:
            # refine a scalar search geometrically between the grid's neighbours
            step = (grid[1] / grid[0]) ** 0.5
            for _ in range(3):
                for value in (best[1] / step, best[1] * step):
                    try:
                        trial = fit_at(cand, value)
                    except ValueError:
                        continue
                    if trial[0] > best[0]:
                        best = trial
                step **= 0.5
        if best is None:
            unfitted[cand.name] = why
            continue
        (physical, _), value, fit = best
        score, tr, te = eq.score(cand, physical, fit, opt)
        twin = twin_score(cand, value) if score > opt.threshold else 0.0
        score -= twin  # what the equations make of this rig's motion without any effect is no evidence
        params = nominal_params(fit)
        effect = cand.effects(value, fit.theta)
        gain, fr, sim = math.nan, {}, None
        if opt.free_run or score > opt.threshold:
            # the simulated model: the searched value polished by free-run error on the
            # TRAINING part (equation error biases it a little, and a free run can be sensitive)
            models = [(params, effect)]
            if cand.refine:
                for f in POLISH:
                    try:
                        pf = fit_at(cand, value * f)[2]
                    except ValueError:
                        continue
                    models.append((nominal_params(pf), cand.effects(value * f, pf.theta)))
            if hasattr(cand, "free_run_variables") and score > opt.threshold:
                models.append(_output_error(cand, params, effect, s, cfg, split, p_nom, float(sig.vl[0])))
            best_run = None
            for p_m, e_m in models:
                run = simulate(p_m, e_m)
                err = mean_nrmse(channel_scores(measured, run.measured, slice(0, split)))
                if best_run is None or err < best_run[0]:
                    best_run = (err, run, p_m, e_m)
            _, run, params, effect = best_run
            sim = run.measured
            fr = channel_scores(measured, sim, test)
            gain = free_run_gain(run, fr, fr_nom)
        results.append(CandidateResult(
            name=cand.name, equation=cand.equation, value=value, score=float(score),
            residual_ratio={g: te[g] / nom_te[g] if nom_te[g] > 0 else 1.0 for g in BLOCKS},
            train_ratio={g: tr[g] / nom_tr[g] if nom_tr[g] > 0 else 1.0 for g in BLOCKS},
            gain=float(gain), freerun=fr, params=params, effect=effect, caveat=cand.caveat, twin=float(twin),
            plausible=cand.plausible(effect), simulated=sim,
            residuals={g: (fit.blocks[g].rows, fit.residuals[g]) for g in BLOCKS}))
        fits[cand.name] = (cand, value, fit)
    if progress is not None:
        progress(len(library), len(library), library[-1].name)
    results.sort(key=lambda c: -c.score)

    def pair(first, second):
        # both extensions at once, each at its own best value, scored against the first alone
        (c1, v1, f1), (c2, v2, _) = fits[first], fits[second]
        spec = merge_specs(c1.spec(v1), c2.spec(v2))
        if spec is None:
            return None
        try:
            f = eq.fit(spec, theta0)
        except ValueError:
            return None
        tr1, te1 = _mse_split(f1, split, floors)
        tr, te = _mse_split(f, split, floors)
        ok = _log_ratio(tr1, tr) > 0 and c2.admissible(f.theta)
        eff = {**c1.effects(v1, f.theta), **c2.effects(v2, f.theta)}
        return (_log_ratio(te1, te) - opt.penalty * c2.n_extra if ok else 0.0), f, eff

    def pair_gain(fit, effect):  # two extensions fitted together (``pair``), simulated as one
        run2 = simulate(nominal_params(fit), effect)
        return free_run_gain(run2, channel_scores(measured, run2.measured, test), fr_nom)

    def probe(names):
        # each family's score less what it scores on the nominal model's twin, as a candidate's
        got = probe_fits(names, fits, sig, cfg, split, theta0, cache, nominal, floors, opt.penalty)
        tw = twin_equations() if got else None
        if tw is None:
            return got
        null = probe_fits(names, fits, tw.sig, cfg, split, tw.theta0, tw.cache, tw.nominal, tw.floors, opt.penalty)
        return {fam: (sc - max(null[fam][0], 0.0) if fam in null else sc, base, f)
                for fam, (sc, base, f) in got.items()}

    def score_of(nom_fit, ext_fit):
        fl = _floors(nom_fit, split)
        (ntr, nte), (tr, te) = _mse_split(nom_fit, split, fl), _mse_split(ext_fit, split, fl)
        return _log_ratio(ntr, tr), _log_ratio(nte, te)

    def reach():  # asked only when Stribeck friction was ranked, so is in the library
        return stribeck_reach(sig, cfg, split, cfg.h, nominal.blocks, theta0, opt.threshold, opt.penalty, score_of,
                              cache)

    def hump(stribeck):  # asked only when nothing earned its place
        cand, others = fits[stribeck.name][0], []
        for v_s in cand.V_S_GRID:  # the hump model's identification at each searched v_s
            if v_s == stribeck.value:
                continue
            try:
                f = fit_at(cand, v_s)[2]
            except ValueError:  # as in the search: a value the record's rows cannot fit
                continue
            others.append((nominal_params(f), cand.effects(v_s, f.theta)))
        return hump_evidence(s, cfg, split, p_nom, stribeck.params, stribeck.effect, sig.vl, fr_nom, others)

    verdict = decide(results, p_nom, impossible, nominal, sig, split, cfg, opt, pair, probe, reach, pair_gain, hump)
    ev = verdict.hump
    if ev is not None:  # the named model is the hump's free-run fit
        results = [replace(c, value=ev.effect["stribeck_v_s"], gain=ev.gain_nominal, freerun=ev.freerun,
                           params=ev.params, effect=dict(ev.effect), plausible=True, simulated=ev.run.measured)
                   if c.name == verdict.cause else c for c in results]
    return AuditResult(
        cause=verdict.cause, causes=verdict.causes, confident=verdict.confident, note=verdict.note,
        words=verdict.words, structure=verdict.structure, obeys=verdict.obeys, effect=verdict.effect,
        stribeck_reach=verdict.stribeck_reach, unfitted=unfitted,
        glitches={ch: int(n) for ch, n in zip(("x1", "x3", "x4", "x5"), replaced)},
        candidates=results, params_nominal=p_nom,
        freerun_nominal=fr_nom or {}, residual_var_nominal=nom_te, split=split,
        t=np.arange(sig.n) * cfg.h, measured=measured, simulated_nominal=sim_nom,
        residuals_nominal={g: (nominal.blocks[g].rows, nominal.residuals[g]) for g in BLOCKS})
