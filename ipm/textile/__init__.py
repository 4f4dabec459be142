"""Textile measures of a yarn, in the units a lab reports (``ipm measure``): from a photo,
net-free and render-free (:mod:`ipm.textile.image`), written as a lab files them
(:mod:`ipm.textile.report`)."""
