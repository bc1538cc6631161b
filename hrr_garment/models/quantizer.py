"""Grouped Gumbel-Softmax quantiser: the shared discrete code space (paper 3.4).

A code is G groups of K classes (default 512 x 8: 4,096 logits). Each (group, class) has a learned
embedding of ``dim`` values; a code's embedding is the concatenation over groups of its chosen
classes' embeddings, (G x dim). Training draws soft Gumbel-Softmax samples and passes hard one-hot
codes forward with the soft sample's gradient (straight-through); evaluation takes the argmax,
deterministic. Both encoders (motion and garment) quantise through the same instance, so their
codes live in one space and can be compared class by class.

Collapse guard: ``diversity_loss`` is log K minus the entropy of the batch-averaged class
distribution per group (0 when every class is used equally often), and ``usage`` counts dead
classes and per-group perplexity for the training log.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F


def group_entropy(logits: torch.Tensor) -> torch.Tensor:
    """Mean over groups of the entropy (nats) of softmax(logits); (..., G, K) -> (...).
    0 for a one-hot distribution, log K for a uniform one."""
    logp = F.log_softmax(logits, dim=-1)
    return -(logp.exp() * logp).sum(-1).mean(-1)


@dataclass(frozen=True)
class CodeUsage:
    """How evenly codes use the classes: dead classes and per-group perplexity."""

    dead: int  # (group, class) pairs never chosen
    perplexity: float  # mean over groups of exp(entropy of the class frequencies); K when uniform
    total: int  # G x K


class GumbelQuantizer(nn.Module):
    """G groups of K classes with learned embeddings; see the module docstring."""

    def __init__(self, groups: int = 512, classes: int = 8, dim: int = 8):
        super().__init__()
        self.groups, self.classes, self.dim = groups, classes, dim
        self.embedding = nn.Parameter(torch.randn(groups, classes, dim) / math.sqrt(dim))

    @property
    def logits_size(self) -> int:
        return self.groups * self.classes

    @property
    def embedding_size(self) -> int:
        return self.groups * self.dim

    def split(self, logits: torch.Tensor) -> torch.Tensor:
        """(B, G * K) -> (B, G, K)."""
        return logits.reshape(*logits.shape[:-1], self.groups, self.classes)

    def codes(self, logits: torch.Tensor, temperature: float = 1.0) -> torch.Tensor:
        """(B, G * K) logits -> (B, G, K) one-hot codes. In training mode: Gumbel-Softmax at
        ``temperature`` with a straight-through hard sample; in eval mode: the argmax."""
        logits = self.split(logits)
        if not self.training:
            return F.one_hot(logits.argmax(-1), self.classes).to(logits.dtype)
        return F.gumbel_softmax(logits, tau=temperature, hard=True, dim=-1)

    def embed(self, codes: torch.Tensor) -> torch.Tensor:
        """(B, G, K) one-hot (or soft) codes -> (B, G * dim) embedding."""
        return torch.einsum("bgk,gkd->bgd", codes, self.embedding).reshape(codes.shape[0], -1)

    def forward(self, logits: torch.Tensor, temperature: float = 1.0) -> tuple[torch.Tensor, torch.Tensor]:
        codes = self.codes(logits, temperature)
        return codes, self.embed(codes)

    def diversity_loss(self, logits: torch.Tensor) -> torch.Tensor:
        """log K - entropy of the batch-mean class distribution, averaged over groups (>= 0)."""
        mean_p = F.softmax(self.split(logits), dim=-1).mean(0)  # (G, K)
        entropy = -(mean_p * torch.log(mean_p.clamp_min(1e-12))).sum(-1)
        return math.log(self.classes) - entropy.mean()

    def usage(self, indices: torch.Tensor) -> CodeUsage:
        """From argmax class indices (N, G) of many codes."""
        counts = F.one_hot(indices.long(), self.classes).sum(0).double()  # (G, K)
        freq = counts / counts.sum(-1, keepdim=True).clamp_min(1)
        entropy = -(freq * torch.log(freq.clamp_min(1e-12))).sum(-1)
        return CodeUsage(int((counts == 0).sum()), float(entropy.exp().mean()), self.groups * self.classes)
