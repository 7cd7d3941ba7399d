"""File readers and writers: BVH motion, WAV audio, word-level transcripts, corpus layouts."""
from ..skeleton import Motion, Skeleton  # noqa: F401
from .audio import Audio, load_audio, save_wav  # noqa: F401
from .bvh import load_bvh, save_bvh  # noqa: F401
from .corpus import Corpus, Participant, Session, load_corpus  # noqa: F401
from .transcripts import load_transcript, save_transcript_tsv  # noqa: F401
