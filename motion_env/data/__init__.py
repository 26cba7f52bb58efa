"""Training data, built offline: BVH folders -> a HumanML3D-layout dataset with captions.

Nothing at run time imports this package; the trainers and the evaluation read what it writes.
"""
