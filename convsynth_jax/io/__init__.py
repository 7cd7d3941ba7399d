"""File readers and writers: BVH motion, WAV audio, word-level transcripts, corpus layouts."""
from .bvh import load_bvh, save_bvh  # noqa: F401
from ..skeleton import Motion, Skeleton  # noqa: F401

try:  # filled in by the transcript/audio/corpus modules
    from .transcripts import load_transcript  # noqa: F401
except ImportError:  # pragma: no cover
    pass
try:
    from .audio import load_audio, Audio  # noqa: F401
except ImportError:  # pragma: no cover
    pass
try:
    from .corpus import load_corpus, Corpus, Session, Participant  # noqa: F401
except ImportError:  # pragma: no cover
    pass
