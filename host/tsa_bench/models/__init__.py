"""The thesis's chapter 3-4 models (issue 7): Preisach, polynomial, rate-dependent
Prandtl-Ishlinskii with creep and transient decay (strain-resistance), its self-sensing
inverse, TSA and soft-manipulator kinematics; fitting to run files and a saved-model format;
the load-strain model of `tsa-bench estimate` (:mod:`.load_strain`, used by control/).

See docs/models.md for the equations, units and the `tsa-bench fit | predict | manipulator` commands.
"""
