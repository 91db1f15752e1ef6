"""Named scenario files (*.scenarios.yaml) shipped with sm2ith_drake."""
