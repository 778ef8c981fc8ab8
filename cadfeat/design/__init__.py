"""The design side of the data flow: from per-pose measures to a redesigned part (thesis ch. 2, 3.4, 4.4, 5).

- ``objectives``: aggregation over the trajectory (eq. 3.24, 4.33), normalisation and combination
  (weighted sum eq. 2.6, max-min eq. 3.26/5.2, constraint, Pareto);
- ``constraints``: the kept functional requirements F_1..F_n (§2.2.2) in fast 2-D form and on the B-rep;
- ``design_space``: the design variables (part parameters or STEP hole moves), bounds, standard sizes;
- ``problem``: the optimisation problem evaluated in batches on feature geometry;
- ``axiomatic``: the design matrix and its verdict (§2.2.4);
- ``optimize``: multistart SLSQP, differential evolution, NSGA-II and the CAD trust-region loop.

Nothing heavy is imported here; import the sub-modules.
"""
