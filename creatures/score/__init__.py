"""The score creature's motor system (thesis, "(void *): a cast of characters"): tiles of
precomposed music laid out just in time under behaviour control.

The thesis recasts (void*)'s custom output layer in its later vocabulary — "behavior system →
action-tuples; output layer → motor system; temporal constraints → either the action-tuple's
Du context, or motor system; pattern generators → motor programs" — and says "only the very
lowest level representation (the content and metrics for BodyPose) need be changed for the new
motor system to produce notes". So here a :class:`~creatures.score.tiles.Tile` is the node's
content, :mod:`.tile_graph` its metric and A*, and :mod:`.layout` the output layer that lays
tiles out on the beat, stretched to the colony's tempo, just before they are played.
"""
