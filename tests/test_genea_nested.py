"""The GENEA 2023 release's nested layout (<split>/{main-agent,interloctr}/{bvh,wav,tsv}/...) reads
as the flat layout of the same files: same sessions, byte-identical Table 1 (task=cooccurrence)."""
from __future__ import annotations

import shutil

import pytest

from convsynth_jax.config import compose, run_task
from convsynth_jax.errors import MissingFileError
from convsynth_jax.io import load_corpus


@pytest.fixture(scope="module")
def layouts(tiny_corpus_dir, tmp_path_factory):
    """(flat, nested) copies of one session of the tiny corpus."""
    base = tmp_path_factory.mktemp("genea_layouts")
    flat, nested = base / "flat", base / "release"
    flat.mkdir()
    for f in tiny_corpus_dir.glob("session01_*"):
        shutil.copy2(f, flat / f.name)
    for d in (flat, nested):
        d.mkdir(exist_ok=True)
        shutil.copy2(tiny_corpus_dir / "corpus.json", d / "corpus.json")
    for f in flat.glob("session01_*"):
        role = f.stem.split("_", 1)[1]
        dest = nested / "trn" / role / f.suffix[1:] / f.name
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(f, dest)
    (nested / "trn" / "metadata.csv").write_text("session01,1,2,finger_incl,finger_incl\n")
    return flat, nested


def test_nested_layout_same_sessions(layouts):
    flat, nested = layouts
    a, b = load_corpus(flat), load_corpus(nested)
    assert [s.name for s in a.sessions] == [s.name for s in b.sessions] == ["session01"]
    for pa, pb in zip(a.sessions[0].participants, b.sessions[0].participants):
        assert (pa.role, pa.character, pa.motion_path.name, pa.audio_path.name, pa.transcript_path.name) == \
               (pb.role, pb.character, pb.motion_path.name, pb.audio_path.name, pb.transcript_path.name)
    assert b.metadata["genea_metadata"]["trn"][0][0] == "session01"
    assert load_corpus(nested / "trn").sessions[0].name == "session01"      # one split as the root
    c = load_corpus(nested, characters={"main-agent": "anna"})
    assert c.sessions[0].participants[0].character == "anna"


def test_nested_layout_same_table1(layouts, tmp_path):
    flat, nested = layouts
    out = {}
    for name, root in (("flat", flat), ("nested", nested)):
        run_task(compose(["task=cooccurrence", "corpus=genea", f"corpus.root={root}", f"cache_dir={tmp_path / name}",
                          "progress=false"]), tmp_path / f"out_{name}")
        out[name] = (tmp_path / f"out_{name}" / "cooccurrence.csv").read_bytes()
    assert out["flat"] == out["nested"] and len(out["flat"]) > 100


def test_nested_layout_missing_file(layouts, tmp_path):
    _, nested = layouts
    broken = tmp_path / "broken"
    shutil.copytree(nested, broken)
    (broken / "trn" / "interloctr" / "wav" / "session01_interloctr.wav").unlink()
    with pytest.raises(MissingFileError, match="session01_interloctr.wav"):
        load_corpus(broken)
