"""Robot models (URDF) shipped with sm2ith_drake; see package.xml."""
