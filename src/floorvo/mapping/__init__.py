"""Keyframe global map and relocalisation (paper 003: Cao et al., J. Robotics 2017).

* :mod:`~floorvo.mapping.similarity`: content-based similarity of two frames (section 3.1).
* :mod:`~floorvo.mapping.keyframes`: keyframe extraction and global poses (section 3.2, eq. 24).
* :mod:`~floorvo.mapping.map`: the map (build, save, load).
* :mod:`~floorvo.mapping.retrieval`: bag of binary words for candidate keyframes.
* :mod:`~floorvo.mapping.localize`: a live frame's global pose from the map alone.
* :mod:`~floorvo.mapping.fused`: the ``map-fused`` estimator (odometry between map fixes).
* :mod:`~floorvo.mapping.localize_run`: ``floorvo localize`` as a library function.
"""
