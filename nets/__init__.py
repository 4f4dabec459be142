"""ipm.nets: the neural ensembles that give the first guess of a yarn's parameters.

Paper vocabulary: encoder f (:mod:`~ipm.nets.encoders`), regression head h
(:mod:`~ipm.nets.heads`), decoder d (:mod:`~ipm.nets.decoder`), losses L_regress, L_recon,
L_latent (:mod:`~ipm.nets.losses`).  One net per :class:`~ipm.nets.tasks.Task`; presets in
:mod:`~ipm.nets.config`; training in :mod:`~ipm.nets.train`; inference::

    from ipm.nets.ensemble import Ensemble
    from ipm.photo import Photo

    params = Ensemble.load(models_dir).predict(Photo.read("yarn.png", pixel_size_mm=0.01))

This package imports torch only in its submodules, so ``import ipm`` stays light.
"""
