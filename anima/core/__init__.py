"""Pure maths shared by every stage: rotations, cameras, temporal filters. Imports no sibling package.

Conventions (settled once, pinned by tests in tests/core):

* Units: centimetres for face-model geometry (ICT-FaceKit's native unit), metres in exported glTF,
  seconds for time; every sequence stores its frame rate.
* Camera space is right-handed: +x to the image right, +y up, +z towards the viewer (OpenGL style).
  A face looking into the camera looks along +z.
* Image space: u to the right, v down, in pixels, origin at the top-left corner of the top-left pixel.
* Head pose: model-to-camera rotation R and translation t; camera space point X = s * R @ V + t.
* Projection is scaled orthographic (weak perspective, as in 3DDFA): the image point of camera-space X
  is (u, v) = (X[0], -X[1]); the image offset is carried by t (see camera.py).
* Euler angles for head yaw/pitch/roll follow ARKit / Live Link Face: yaw about +y, pitch about +x,
  roll about +z, R = Ry(yaw) @ Rx(pitch) @ Rz(roll), in radians.
"""
