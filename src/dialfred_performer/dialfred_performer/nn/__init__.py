"""The performer's parts, one nn.Module each: language, visual and action encoders, the multimodal
transformer and its heads. `dialfred_performer.model.Performer` composes them."""

from .enc_action import ActionEmbedding
from .enc_lang import LanguageEncoder
from .enc_perceived import PerceivedFrames
from .enc_visual import VisualEncoder
from .enc_vl import MultimodalEncoder, attention_allowed
from .heads import ActionHead, PointerHead

__all__ = ['ActionEmbedding', 'LanguageEncoder', 'PerceivedFrames', 'VisualEncoder', 'MultimodalEncoder', 'attention_allowed',
           'ActionHead', 'PointerHead']
