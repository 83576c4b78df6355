"""gnppdsl.nlp: graph-NLPs (paper 000, Sec. IV), their casadi assembly and elastic feasibility
check, and Algorithm 1 (small infeasible subgraphs, Sec. VI).

Modules: `lowering` (the expression language -> casadi expressions), `body_compiler`
(casadi Functions and derivatives built and cached per body structure), `evaluate` (independent numpy
checker), `graph` (GraphNLP over its own small graph class), `feasibility` (ipopt, elastic form), `subgraph`
(double binary search, relaxations, convergence heuristic), `geometry_protocol` (what the
geometry layer injects). Import the submodules directly; this package imports nothing heavy.
"""
