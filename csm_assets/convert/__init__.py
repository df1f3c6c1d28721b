"""Scene conversion and the pipelines around it.

- :mod:`.pipeline`: ``convert``, a chain of small steps over the scene model.
- :mod:`.maps`: the step maps of a scene being converted; :mod:`.pick`: ``--max-error``'s picks.
- :mod:`.output_folder`: staging and publishing; :mod:`.manifest`: what outputs were made from;
  :mod:`.inputs`: the inputs as they were read (a manifest records nothing else).
- :mod:`.batch`: many scenes, in parallel, on the local cores or any executor.
"""
