"""THE scene's path tracer: Mitsuba's ``path`` with a better choice of lamp at every vertex.

Mitsuba's ``path`` picks the light of each next-event estimate with fixed probabilities (the
lamps' ``sampling_weight``).  On a round fiber that wastes samples: past a fiber's terminator
one soft box is below the surface's horizon, and every sample that picks it adds zero, so
the other lamp's light comes with weight ``1 / p`` and the pixel is noisy where it matters
(shaded fiber sides).  ``ipm_path`` picks each area lamp with probability proportional to

    reach_i = sampling_weight_i * max(cos theta_i + sin phi_i, 0),

theta_i the angle between the shading normal and the direction to the lamp's centre, phi_i
the angular radius of the lamp's bounding sphere: ``reach_i`` is zero only where all of that
sphere is below the horizon, where the fibers' and the card's reflect-only BSDFs return zero
for the lamp, so the estimate stays unbiased.  Infinite lamps (the room light) are not
light-sampled at all: the BSDF's cosine-weighted samples find a constant sky well, and
Mitsuba samples it over the whole sphere, half of it below the surface.  Lamps hit by BSDF
samples are weighted against this choice by multiple importance sampling (power
heuristic), as in ``path``.

The expected image is ``path``'s (``tests/test_render.py`` compares them); only the noise
and the time change: less noise than ``path`` with :data:`ipm.render.scene.LIGHT_WEIGHTS`
at the same samples (benchmarks/results/noise_levers.md).  Emitters are hidden
from camera rays (the scene's ``hide_emitters``) and paths end after ``max_depth``
vertices as in ``path``; no Russian roulette (the scene's depth of 3 ends paths before
``path``'s default rr_depth).

Python integrators run per ray in scalar variants (far too slow), so there the scene keeps
Mitsuba's ``path`` (:func:`ipm.render.scene.scene_dict`).
"""

from __future__ import annotations

from types import ModuleType

PLUGIN = "ipm_path"
_registered: set[str] = set()


def register(mi: ModuleType) -> None:
    """Register :data:`PLUGIN` for Mitsuba's current variant (plugins are per variant)."""
    if mi.variant() in _registered:
        return
    cls = _integrator_class(mi)
    mi.register_integrator(PLUGIN, lambda props: cls(props))
    _registered.add(mi.variant())


def mis_weight(pdf_a, pdf_b):
    """The power heuristic's weight of the strategy with density ``pdf_a``."""
    import drjit as dr

    a2, b2 = dr.square(pdf_a), dr.square(pdf_b)
    w = a2 / (a2 + b2)
    return dr.select(dr.isfinite(w), w, 0.0)


def _integrator_class(mi: ModuleType) -> type:
    import drjit as dr

    class LampReachPath(mi.SamplingIntegrator):
        def __init__(self, props):
            super().__init__(props)
            self.max_depth = props.get("max_depth", 3)

        @staticmethod
        def lamps(scene):
            """(emitter, bounding-sphere centre, radius, sampling weight) of the area lamps."""
            out = []
            for shape in scene.shapes():
                if shape.is_emitter():
                    box = shape.bbox()
                    out.append((shape.emitter(), box.center(), dr.norm(box.extents()) / 2,
                                shape.emitter().sampling_weight()))
            return out

        @staticmethod
        def choice(lamps, si):
            """Each lamp's probability of being sampled from ``si`` (all zero: none reaches)."""
            reach = []
            for _, centre, radius, weight in lamps:
                d = centre - si.p
                dist = dr.norm(d)
                cos = dr.dot(si.sh_frame.n, d) / dist
                reach.append(weight * dr.select(dist > radius,
                                                 dr.maximum(cos + radius / dist, 0.0), 1.0))
            total = sum(reach[1:], reach[0])
            inv = dr.select(total > 0, dr.rcp(total), 0.0)
            return [r * inv for r in reach]

        @dr.syntax
        def sample(self, scene, sampler, ray, medium=None, active=True):
            # dr.syntax recompiles this body in the module's globals: no closure variables
            import drjit as dr
            import mitsuba as mi

            lamps = self.lamps(scene)
            ctx = mi.BSDFContext()
            ray = mi.Ray3f(ray)
            L = mi.Spectrum(0.0)
            beta = mi.Spectrum(1.0)
            depth = mi.UInt32(0)
            active = mi.Bool(active)
            valid = mi.Bool(False)
            si_prev = dr.zeros(mi.SurfaceInteraction3f)
            bsdf_pdf_prev = mi.Float(1.0)
            choice_prev = [mi.Float(0.0) for _ in lamps]  # the lamp choice at si_prev
            while active:
                si = scene.ray_intersect(ray, active)
                valid |= (depth == 0) & si.is_valid()
                # light found by the last BSDF sample (camera rays: emitters hidden)
                found = active & (depth > 0)
                ds = mi.DirectionSample3f(scene, si=si, ref=si_prev)
                lamp_pdf = mi.Float(0.0)
                for (emitter, _, _, _), p in zip(lamps, choice_prev, strict=True):
                    hit = found & (ds.emitter == mi.EmitterPtr(emitter))
                    lamp_pdf[hit] = p * emitter.pdf_direction(si_prev, ds, hit)
                L[found] += beta * mis_weight(bsdf_pdf_prev, lamp_pdf) * ds.emitter.eval(si, found)

                active &= si.is_valid() & (depth + 1 < self.max_depth)
                bsdf = si.bsdf(ray)
                # next-event estimation: one lamp, chosen by its reach; the choice reuses the
                # first coordinate of the stratified 2D sample, as Mitsuba's does
                u = sampler.next_2d(active)
                em_active = mi.Bool(False)
                em_ds = dr.zeros(mi.DirectionSample3f)
                em_weight = mi.Spectrum(0.0)
                lo = mi.Float(0.0)
                choice = self.choice(lamps, si)
                for i, ((emitter, _, _, _), p) in enumerate(zip(lamps, choice, strict=True)):
                    # the last lamp takes the rest of [0, 1), which rounding may leave
                    last = i == len(lamps) - 1
                    pick = active & (p > 0) & (u.x >= lo) & ((u.x < lo + p) | last)
                    u_lamp = mi.Point2f(dr.minimum((u.x - lo) / p, dr.one_minus_epsilon(mi.Float)),
                                        u.y)
                    ds_i, w_i = emitter.sample_direction(si, u_lamp, pick)
                    em_ds[pick] = ds_i
                    em_ds.pdf[pick] = ds_i.pdf * p
                    em_weight[pick] = w_i / p
                    em_active |= pick
                    lo += p
                em_active &= (em_ds.pdf != 0) & ~scene.ray_test(si.spawn_ray_to(em_ds.p),
                                                                em_active & (em_ds.pdf != 0))
                s1, s2 = sampler.next_1d(active), sampler.next_2d(active)
                f, bsdf_pdf = bsdf.eval_pdf(ctx, si, si.to_local(em_ds.d), em_active)
                L[em_active] += beta * mis_weight(em_ds.pdf, bsdf_pdf) * f * em_weight

                bs, bsdf_weight = bsdf.sample(ctx, si, s1, s2, active)
                beta *= bsdf_weight
                ray = si.spawn_ray(si.to_world(bs.wo))
                si_prev = si
                bsdf_pdf_prev = bs.pdf
                choice_prev = choice
                active &= dr.max(beta) > 0
                depth += 1
            return L, valid, []

    return LampReachPath
