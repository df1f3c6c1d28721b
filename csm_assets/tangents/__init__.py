"""Tangent frames for triangle meshes.

- :mod:`.frames`: MikkTSpace tangents per corner and corner welding for vertex buffers.
- :mod:`.mikktspace`: the port of mikktspace.c's ``genTangSpaceDefault``; :mod:`.topology`: its
  welding and neighbour search.
- :mod:`.mesh_checks`: the tangents of converted meshes and what makes them doubtful; triangle areas.
"""
