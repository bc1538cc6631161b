"""The one optimisation pass every exported graph gets (the step's, the skin collider's): onnxscript's
``optimize_ir`` once (constants folded, its rewrite rules, unused nodes removed, initialisers lifted
and shared, common subexpressions merged), where torch's exporter runs it twice and then its fusions
(onnxruntime fuses operators itself when it loads a graph).

One of onnxscript's default rules is left out: ``SlicesSplit`` matches every pair of ``Slice`` nodes
that read one tensor (a two-rooted pattern: the pairs grow as the square of the slices) to find the
two halves of a last axis that a ``Split`` could give at once. The step slices its coordinates and
planes everywhere and halves nothing: on the 1,046-vertex model's step, it fired on no pair and took
4.5 of the optimiser's 9.1 s on the capsules' graph and 15.5 of 25.2 s on the mesh's (docs/export.md).
"""

from __future__ import annotations

SLOW_UNUSED_RULES = ("SlicesSplit",)  # default rewrite rules the pass leaves out (their names)


def optimise_graph(model) -> None:
    """Optimise the ONNX IR ``model`` in place: ``optimize_ir``'s passes, once, with its default
    rewrite rules but :data:`SLOW_UNUSED_RULES` (where this onnxscript names its rules otherwise,
    ``optimize_ir`` itself, once)."""
    from onnxscript import optimizer, rewriter

    rules = [rule for rule in _default_rules(rewriter) if getattr(rule, "name", "") not in SLOW_UNUSED_RULES]
    passes = _passes(rules) if rules else None
    if passes is None:
        optimizer.optimize_ir(model, num_iterations=1)
        return
    passes(model)  # every pass works in place


def _default_rules(rewriter) -> list:
    """onnxscript's default rewrite rules (what ``optimize_ir`` applies), or none where they are
    not where this version of it keeps them."""
    rules = getattr(rewriter, "_DEFAULT_REWRITE_RULES", None)
    return list(rules) if isinstance(rules, tuple | list) else []


def _passes(rules: list):
    """``optimize_ir(model, num_iterations=1)``'s passes, in its order, with ``rules`` for its
    rewrite pass (None where this onnxscript lacks one of them)."""
    try:
        import onnx_ir as ir
        from onnx_ir.passes import common
        from onnxscript.optimizer import _constant_folding as folding
        from onnxscript.rewriter import RewritePass
    except ImportError:
        return None
    once = ir.passes.PassManager(
        [
            folding.FoldConstantsPass(
                shape_inference=True,
                input_size_limit=folding.DEFAULT_CONSTANT_FOLD_INPUT_SIZE_LIMIT,
                output_size_limit=folding.DEFAULT_CONSTANT_FOLD_OUTPUT_SIZE_LIMIT,
                should_fold=lambda node: None,
            ),
            RewritePass(rules),
            common.RemoveUnusedNodesPass(),
            common.RemoveUnusedFunctionsPass(),
            common.RemoveUnusedOpsetsPass(),
        ],
        steps=1,
    )
    return ir.passes.Sequential(
        common.InlinePass(),
        once,
        common.RemoveUnusedNodesPass(),
        common.LiftConstantsToInitializersPass(lift_all_constants=True, size_limit=0),
        common.LiftSubgraphInitializersToMainGraphPass(),
        common.DeduplicateInitializersPass(),
        common.CommonSubexpressionEliminationPass(),
        common.OutputFixPass(),
        common.NameFixPass(),
    )
