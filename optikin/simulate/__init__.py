"""Simulated labs: recordings made by physics the models of optikin do not contain, with their truth known.

* :mod:`optikin.simulate.tendon_lab`: a hanging tendon-driven three-section trunk (Cosserat-rod statics of
  :mod:`optikin.physics`), a tip payload, tendon friction and hysteresis, a mount offset, tracked bodies off
  the backbone, marker noise and occlusions, on a grid of six motor inputs; source ``tendon_lab`` of data
  family ``recordings``.
"""
