// Upper hemisphere |x| = R, z >= 0 (femshell.mesh.hemisphere). Curve: equator (z = 0).
// hole > 0: the cap with polar angle < hole (radians, < Pi/2) is left out; curve hole.
// gmsh -2 -setnumber R 30 -setnumber h 2 -setnumber hole 0.3 hemisphere.geo -o hemi.msh
DefineConstant[ R = 1.0,     // radius (design units)
                h = 0.1,     // target edge length
                hole = 0.0,  // polar angle of the hole around the pole (0: no hole)
                seed = 0 ];
SetFactory("OpenCASCADE");
General.NumThreads = 1;
Mesh.Algorithm = 6;
Mesh.RandomSeed = seed;
Mesh.MeshSizeMin = h;
Mesh.MeshSizeMax = h;
Mesh.MeshSizeFromCurvature = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeExtendFromBoundary = 0;

// the zone of the ball between latitudes 0 and Pi/2 - hole; keep its spherical face only
Sphere(1) = {0, 0, 0, R, 0, Pi/2 - hole, 2*Pi};
e = 1e-6 * R;
zh = R * Cos(hole);
flat() = Surface In BoundingBox{-R - e, -R - e, -e, R + e, R + e, e};
If (hole > 0)
  flat() += Surface In BoundingBox{-R - e, -R - e, zh - e, R + e, R + e, zh + e};
EndIf
Delete{ Volume{1}; }
Delete{ Surface{flat()}; }        // not recursive: the rim curves stay with the spherical face
Physical Curve("equator") = Curve In BoundingBox{-R - e, -R - e, -e, R + e, R + e, e};
If (hole > 0)
  Physical Curve("hole") = Curve In BoundingBox{-R - e, -R - e, zh - e, R + e, R + e, zh + e};
EndIf
Physical Surface("surface") = Surface{:};
