"""gnppdsl: a modelling language, compiler and conflict-driven solver for TAMP posed as PNTC.

Layers (data flows one way): lang -> ir -> compile -> solve (logic, nlp, conflicts) -> cli.
geometry sits under nlp; reach is R-LGP.
"""
__version__ = "0.1.0"
