"""Training data, built offline: BVH folders -> a HumanML3D-layout dataset with captions.

Nothing at run time imports this package; the trainers and the evaluation read what it writes.

- :mod:`.dataset`: the HumanML3D layout, splits, reading a dataset back (``read_split``,
  ``load_stats``, caption files);
- :mod:`.build`: ``build_dataset`` (``motion-env data build``), with the per-file import jobs in
  :mod:`.jobs` and the ``Mean.npy`` / ``Std.npy`` statistics in :mod:`.stats`;
- :mod:`.captions`: captions from the labels of Bandai Namco and CMU files or from file names.
"""
