"""Fuzzed readers: a malformed BVH, WAV, TextGrid, TSV/CSV, IBM JSON transcript,
corpus manifest (YAML, CSV) or GENEA folder gives the project's error naming the file, never another
exception nor a hang. experiments/bench/fuzz_readers.py runs >= 2,000 cases per reader."""
from __future__ import annotations

import shutil

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from convsynth_jax.testing.fuzz import KINDS, READERS, Mutation, run_case, write_seeds

CORPORA = ("manifest_yaml", "manifest_csv", "genea")
mutation = st.builds(Mutation, st.sampled_from(KINDS), st.integers(0, 1 << 20), st.integers(0, 1 << 10))


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    root = tmp_path_factory.mktemp("fuzz_seeds")
    write_seeds(root)
    return root


@pytest.mark.parametrize("reader", sorted(READERS))
def test_seed_loads(reader, seeds, tmp_path):
    out = run_case(reader, seeds, tmp_path / "w", [])
    assert out.status == "loaded", out.detail


@pytest.mark.parametrize("reader", sorted(READERS))
def test_malformed_input_gives_the_projects_error_naming_the_file(reader, seeds, tmp_path):
    @settings(max_examples=40 if reader in CORPORA else 100, deadline=5000, database=None, derandomize=True,
              suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
    @given(mutations=st.lists(mutation, min_size=1, max_size=3), file_index=st.integers(0, 50),
           remove=st.booleans() if reader in CORPORA else st.just(False))
    def case(mutations, file_index, remove):
        out = run_case(reader, seeds, tmp_path / "w", mutations, file_index, remove)
        assert out.status in ("loaded", "project_error"), (out.status, out.detail)

    case()


# Defects the fuzzing found (each gave another exception before its fix)

@pytest.mark.parametrize("offset, value", [(16, 0x11), (22, 0)])  # fmt chunk size; channel count 0
def test_damaged_wav_header_gives_audio_error(seeds, tmp_path, offset, value):
    from convsynth_jax.errors import AudioFormatError
    from convsynth_jax.io.audio import load_audio, wav_duration

    data = bytearray((seeds / "clip.wav").read_bytes())
    data[offset] = value
    bad = tmp_path / "bad.wav"
    bad.write_bytes(bytes(data))
    for read in (load_audio, wav_duration):
        with pytest.raises(AudioFormatError, match="bad.wav"):
            read(bad)


@pytest.mark.parametrize("count", ["inf", "-2", "1.5", "1e400"])
def test_textgrid_interval_count_must_be_whole(seeds, tmp_path, count):
    from convsynth_jax.errors import TranscriptFormatError
    from convsynth_jax.io.transcripts import load_transcript

    bad = tmp_path / "bad.TextGrid"
    bad.write_text((seeds / "words.TextGrid").read_text().replace("intervals: size = 3", f"intervals: size = {count}"))
    with pytest.raises(TranscriptFormatError, match=r"bad\.TextGrid: line 14: expected a whole number"):
        load_transcript(bad)


@pytest.mark.parametrize("name, content", [
    ("corpus.yaml", b"sessions:\n  - name: s\xe91\n"),                 # not UTF-8
    ("corpus.csv", b"session,role\xdd,motion\n"),                      # not UTF-8
    ("corpus.csv", b""),                                               # empty
    ("corpus.yaml", b"sessions:\n  - just a name\n"),                  # a session that is not a mapping
    ("corpus.yaml", b"sessions:\n  - participants: [a.bvh]\n"),        # a participant that is not a mapping
    ("corpus.yaml", b"sessions:\n  - participants:\n    - {motion: a.bvh}\n    - {role: b, motion: b.bvh}\n"),  # no role
])
def test_malformed_manifest_gives_format_error_naming_it(seeds, tmp_path, name, content):
    from convsynth_jax.errors import FormatError
    from convsynth_jax.io.corpus import load_manifest

    folder = tmp_path / "m"
    shutil.copytree(seeds / "manifest", folder)
    (folder / name).write_bytes(content)
    with pytest.raises(FormatError, match=name):
        load_manifest(folder / name)


def test_missing_transcript_names_the_manifest(seeds, tmp_path):
    from convsynth_jax.errors import MissingFileError
    from convsynth_jax.io.corpus import load_manifest

    folder = tmp_path / "m"
    shutil.copytree(seeds / "manifest", folder)
    text = (folder / "corpus.yaml").read_text().replace(", transcript: a.tsv", "")
    (folder / "corpus.yaml").write_text(text)
    part = load_manifest(folder / "corpus.yaml").sessions[0].participants[0]
    with pytest.raises(MissingFileError, match=r"corpus\.yaml.*no transcript file"):
        part.load_transcript()
