"""Bark that cracks and sheds (woodification §4-5; docs/model.md §10).

* :mod:`.sheet`: the bark surface of every branch as a triangle mesh in its (phi, s) parameters,
  with the growth strain its rings record, the threshold noise and the elements under it;
* :mod:`.cracks`: the crack simulation on it (stress, separation tensor, crack edges, widths);
* :mod:`.shedding`: the bark's bond to the wood, plates bounded by cracks that come off;
* :mod:`.surface`: what the meshlets' bark vertices show of it (crack primvars and grooves).
"""
