"""The rig's open bus contract: rig quantities, bindings to a database, one codec.

* :mod:`hil.contract.quantity`: what a rig's devices publish to the DUT or take from it;
* :mod:`hil.contract.binding`: which frame and signal of a database (or which ISO 11783-10
  DDI) carries each quantity, with the rule that converts it;
* :mod:`hil.contract.codec`: quantities in, the bound frames out, and back;
* :mod:`hil.contract.database`: any CAN database cantools reads, with compiled fast paths;
* :mod:`hil.contract.registry`: a rig's contract from its own registration;
* :mod:`hil.contract.checks`: everything ``hil profile check`` finds wrong with a binding;
* :mod:`hil.contract.bind`: a starting binding from a database (``hil profile bind``).
"""
