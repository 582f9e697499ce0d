"""``anima dataset report``: a markdown + HTML report of a built dataset, with plots and contact sheets.

Sections: clips removed by each rule (seed 000 §5.1 discusses them), attribute distribution (like seed 000
table 4.4: fraction of kept clips where each attribute occurs), clip-length histogram, splits, example
descriptions, and contact sheets (frames of a few kept clips with the fitted mesh drawn over them).
"""

from __future__ import annotations

import html
from collections import Counter
from pathlib import Path

import numpy as np

from anima.capture.config import FIT_FOR_DETECTORS, CaptureConfig
from anima.capture.pipeline import capture_video
from anima.dataset.storage import check_dataset, read_table
from anima.dataset.windows import clip_events
from anima.io.atomic import write_figure, write_image, write_text
from anima.io.video import read_video
from anima.render.face import render_mesh
from anima.render.videos import SequenceMesh


def _bar(
    plt, path: Path, labels, values, color: str, ylabel: str, size, rotation: int, title: str | None = None
) -> str:
    fig, ax = plt.subplots(figsize=size)
    ax.bar(labels, values, color=color)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    plt.setp(ax.get_xticklabels(), rotation=rotation, ha="right")
    fig.tight_layout()
    write_figure(path, fig, dpi=110)
    plt.close(fig)
    return path.name


def _plots(out: Path, lengths: list[float], attr_frac: dict[str, float], removed: dict[str, int]) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.hist(lengths, bins=np.arange(0, 12.5, 0.5), color="#4477aa")
    ax.set_xlabel("clip length (s)")
    ax.set_ylabel("clips")
    ax.set_title("Clip lengths (kept clips)")
    fig.tight_layout()
    write_figure(out / "clip_lengths.png", fig, dpi=110)
    plt.close(fig)
    files.append("clip_lengths.png")
    if attr_frac:
        names = sorted(attr_frac, key=lambda k: -attr_frac[k])
        files.append(
            _bar(
                plt,
                out / "attributes.png",
                names,
                [attr_frac[n] for n in names],
                "#ee7733",
                "fraction of clips",
                (6, 3),
                40,
                "Attribute distribution",
            )
        )
    files.append(
        _bar(plt, out / "removed.png", list(removed), list(removed.values()), "#aa3377", "clips removed", (5, 3), 30)
    )
    return files


def contact_sheet(source: str, start_s: float, end_s: float, path: Path, n: int = 6, size: int = 160) -> bool:
    """Frames of a clip with the fitted face mesh over them (captures the clip's frames again, face only)."""
    import cv2

    try:
        frames, info = read_video(source, max_frames=int(end_s * 30) + 2)
    except Exception:
        return False
    a, b = int(start_s * info.fps), min(int(end_s * info.fps), len(frames))
    if b - a < 2:
        return False
    seq = capture_video(source, CaptureConfig(face_only=True, max_frames=b, fit=FIT_FOR_DETECTORS), progress=False)
    mesh = SequenceMesh(seq)
    tiles = []
    for f in np.linspace(a, b - 1, n).astype(int):
        img = (
            render_mesh(mesh.camera_vertices(f), mesh.tris, (info.width, info.height), frames[f], 0.5)
            if seq.tracked[f]
            else frames[f]
        )
        tiles.append(cv2.resize(np.concatenate([frames[f], img], 0), (size, 2 * size * info.height // info.width)))
    write_image(path, np.concatenate(tiles, 1))
    return True


def write_report(folder: str | Path, n_examples: int = 4, sheets: int = 3) -> Path:
    folder = Path(folder)
    manifest = check_dataset(folder)
    rep = folder / "report"
    rep.mkdir(exist_ok=True)
    tm = read_table(folder, "text_motion").to_pydict()
    lengths = [e - s for s, e in zip(tm["start_s"], tm["end_s"])]
    occ = Counter()
    for a, row in zip(tm["attributes"], tm["clip_id"]):
        occ.update({n for n, _, _ in clip_events(a, folder, row)})
    n_clips = max(len(tm["clip_id"]), 1)
    frac = {k: v / n_clips for k, v in occ.items()}
    plots = _plots(rep, lengths, frac, manifest["removed_by_rule"])
    sheet_files = []
    for i in range(min(sheets, len(tm["clip_id"]))):
        p = rep / f"sheet_{i}.png"
        if contact_sheet(tm["source"][i], tm["start_s"][i], tm["end_s"][i], p):
            sheet_files.append((p.name, tm["clip_id"][i]))
    md = [
        f"# Dataset report: {folder.name}",
        "",
        f"- videos: {manifest['videos']} ({manifest['videos_done']} done, {len(manifest['videos_failed'])} failed)",
        f"- video seconds: {manifest['seconds_of_video']}, frames: {manifest['frames']}, capture compute: "
        f"{manifest['compute_s']} s",
        f"- clips: {manifest['clips_total']} cut, **{manifest['clips_kept']} kept**; (audio, motion) windows: "
        f"**{manifest['windows']}**",
        "- splits (videos): " + ", ".join(f"{k} {len(v)}" for k, v in manifest["splits"].items()),
        "",
        "## Clips removed by each rule",
        "",
        "| rule | clips |",
        "|---|---|",
    ]
    md += [f"| {k} | {v} |" for k, v in manifest["removed_by_rule"].items()]
    md += [
        "",
        "![removed](removed.png)",
        "",
        "## Attribute distribution (fraction of kept clips)",
        "",
        "| attribute | fraction |",
        "|---|---|",
    ]
    md += [f"| {k} | {v:.2f} |" for k, v in sorted(frac.items(), key=lambda kv: -kv[1])]
    md += [
        "",
        "![attributes](attributes.png)" if "attributes.png" in plots else "",
        "",
        "## Clip lengths",
        "",
        "![lengths](clip_lengths.png)",
        "",
        "## Example descriptions",
        "",
    ]
    for i in range(min(n_examples, len(tm["clip_id"]))):
        md.append(f"**{tm['clip_id'][i]}** ({lengths[i]:.1f} s)")
        md += [f"- {t}" for t in tm["texts"][i][:3]]
        md.append("")
    if manifest["videos_failed"]:
        md += ["## Failed videos", ""] + [f"- {e['source']}: {e['error']}" for e in manifest["videos_failed"]]
    md += ["", "## Contact sheets (top: frames, bottom: fitted mesh)", ""]
    md += [f"**{cid}**\n\n![{name}]({name})\n" for name, cid in sheet_files]
    text = "\n".join(md)
    write_text(rep / "report.md", text)
    body = []
    for line in text.splitlines():
        if line.startswith("!["):
            src = line[line.index("(") + 1 : -1]
            body.append(f'<p><img src="{html.escape(src)}" style="max-width:100%"></p>')
        elif line.startswith("# "):
            body.append(f"<h1>{html.escape(line[2:])}</h1>")
        elif line.startswith("## "):
            body.append(f"<h2>{html.escape(line[3:])}</h2>")
        elif line.startswith("|"):
            cells = [c.strip() for c in line.strip("|").split("|")]
            if set("".join(cells)) <= {"-"}:
                continue
            body.append("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in cells) + "</tr>")
        elif line:
            body.append(f"<p>{html.escape(line)}</p>")
    out_html = []
    in_table = False
    for b in body:
        if b.startswith("<tr>") and not in_table:
            out_html.append("<table border=1 cellpadding=3>")
            in_table = True
        if not b.startswith("<tr>") and in_table:
            out_html.append("</table>")
            in_table = False
        out_html.append(b)
    write_text(
        rep / "report.html", "<html><body style='font-family:sans-serif'>" + "\n".join(out_html) + "</body></html>"
    )
    return rep / "report.md"
