"""Finished chunks of a sweep on disk, so an interrupted campaign resumes where it stopped.

DIR/sweep.chunks/ holds campaign.json (the campaign's settings: what a resume must match) and
one JSON file per finished chunk (its per-sample error values, faults, skips and timing; floats
written with repr, so they read back bit for bit). `crosscheck sweep --resume DIR` loads them,
recomputes only the samples no file covers, and writes the sweep.json an uninterrupted run
writes (everything but meta and timing identical). A complete campaign removes the directory.
Every file is written atomically (crosscheck.runtime.output), so a chunk file is whole or absent.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

from crosscheck.runtime.output import TMP_PREFIX, write_atomic

STORE = "sweep.chunks"
FORMAT = 1
# the campaign settings a resume must share; the executor, chunking and budget may differ
SETTINGS = ("models", "samples", "seed", "index", "engines", "perturb", "formulation", "worst")
SETTINGS += ("derivatives",)


def settings(cfg) -> dict:
    return {"format": FORMAT, **{k: _plain(getattr(cfg, k)) for k in SETTINGS}}


def _plain(x):
    """Tuples as lists: the form the settings have after a JSON round trip."""
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    return x


def chunk_files(directory: Path) -> list[Path]:
    """The stored chunks <model>-<start>.json; not a file still being written or left half
    written by a killed process (its temporary name, TMP_PREFIX..., matches the pattern too)."""
    return [p for p in directory.glob("*-*.json") if not p.name.startswith(TMP_PREFIX)]


class ChunkStore:
    """The finished chunks of one campaign in out_dir/sweep.chunks."""

    def __init__(self, out_dir: str | Path, cfg):
        self.dir = Path(out_dir) / STORE
        self.settings = settings(cfg)

    def start(self, command: str = "") -> None:
        """A new campaign: the chunks of any earlier one in this directory are not its own.
        `command` (the command line that started it) is kept for a resume's meta."""
        shutil.rmtree(self.dir, ignore_errors=True)
        text = json.dumps({**self.settings, "command": command}, indent=1)
        write_atomic(self.dir / "campaign.json", text)

    def save(self, res: dict) -> None:
        if res["completed"] > 0:
            # a finished chunk stays valid after a Ctrl-C (kept for --resume)
            write_atomic(
                self.dir / f"{res['model']}-{res['start']}.json",
                json.dumps(encode(res), allow_nan=True),
                after_interrupt=True,
            )

    def load(self) -> list[dict]:
        """The stored chunk results, in a fixed order (model, start)."""
        out = [decode(json.loads(p.read_text())) for p in chunk_files(self.dir)]
        return sorted(out, key=lambda r: (r["model"], r["start"]))

    def stored_command(self) -> str:
        """The command line that started the stored campaign ("" if not recorded)."""
        try:
            return str(json.loads((self.dir / "campaign.json").read_text()).get("command", ""))
        except (OSError, json.JSONDecodeError):
            return ""

    def remove(self) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)


def stored_settings(out_dir: str | Path) -> dict:
    """The settings of the campaign stored in out_dir, or a one-line error saying why not."""
    from reference.errors import ModelInputError

    path = Path(out_dir) / STORE / "campaign.json"
    if not path.is_file():
        done = (Path(out_dir) / "sweep.json").is_file()
        raise ModelInputError(
            f"--resume {str(out_dir)!r}: no interrupted campaign there (no "
            f"{STORE}/campaign.json" + ("; its sweep.json is complete)" if done else ")")
        )
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ModelInputError(f"--resume: {path} is unreadable ({exc})") from None
    if data.get("format") != FORMAT or not all(k in data for k in SETTINGS):
        raise ModelInputError(
            f"--resume: {path} was written by another version of the sweep; "
            "start the campaign again"
        )
    return data


def _key(k) -> list:
    return list(k)


def encode(res: dict) -> dict:
    """A chunk result as JSON: tuple keys as lists, arrays as lists of floats."""
    t = res["timing"]
    return {
        "model": res["model"],
        "start": res["start"],
        "stop": res["stop"],
        "completed": res["completed"],
        "values": [[*_key(k), [float(x) for x in v]] for k, v in res["values"].items()],
        "soft": [[*_key(k), v] for k, v in res["soft"].items()],
        "skips": [[*_key(k), v] for k, v in res["skips"].items()],
        "faults": res["faults"],
        "timing": {
            **{k: t[k] for k in ("draw_s", "reference_s", "reference_aux_s", "samples")},
            "series": [[*_key(k), list(v)] for k, v in t["series"].items()],
        },
    }


def decode(d: dict) -> dict:
    import numpy as np

    t = d["timing"]
    return {
        "model": d["model"],
        "start": d["start"],
        "stop": d["stop"],
        "completed": d["completed"],
        "values": {
            (e, v, q): np.array([math.nan if x is None else x for x in arr], float)
            for e, v, q, arr in d["values"]
        },
        "soft": {(e, v): s for e, v, s in d["soft"]},
        "skips": {(e, v, q): r for e, v, q, r in d["skips"]},
        "faults": d["faults"],
        "timing": {
            **{k: t[k] for k in ("draw_s", "reference_s", "reference_aux_s", "samples")},
            "series": {(e, v): tuple(x) for e, v, x in t["series"]},
        },
    }
