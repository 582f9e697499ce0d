"""The linear face model (ICT-FaceKit light): import, load, evaluate, regions, landmark correspondence."""

from anima.facemodel.ict import FaceModel, load_face_model  # noqa: F401
