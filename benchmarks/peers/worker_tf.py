"""The authors' HCMT (TensorFlow + Sonnet, github.com/yuyudeep/hcmt) on the exported graph.

    TF_USE_LEGACY_KERAS=1 python benchmarks/peers/worker_tf.py GRAPH.npz AUTHORS_DIR

Their ``core_model.HCMT`` and ``model.ImpactModel`` unchanged, except that ``_build_graph`` takes the exported
edges instead of rebuilding them from the cells and a contact search every call (hcmt's trainer builds graphs in
its data pipeline too, so both sides time the model only). Hierarchy, in their layout: ``m_ids[0]`` every node and
``m_gs[0]`` the level-0 mesh edges, then ``m_ids[l+1]`` = hcmt's ``pool_l``, ``m_gs[l+1]`` = ``level_edges_l``.
A train step is their ``train_step`` (``model.loss`` under a GradientTape, Keras Adam lr 1e-4) in a
``tf.function``; inference ``model(inputs)`` in a ``tf.function``. One intra-op and one inter-op thread."""

from __future__ import annotations

import sys

from protocol import one_thread, serve, warm_up

one_thread()

import numpy as np  # noqa: E402
import tensorflow as tf  # noqa: E402

tf.config.threading.set_intra_op_parallelism_threads(1)
tf.config.threading.set_inter_op_parallelism_threads(1)


def contestant(path: str, authors: str):
    sys.path.insert(0, authors)
    from core_model import HCMT
    from model import ImpactModel
    from util import NodeType

    d = np.load(path)
    levels = sum(k.startswith("pool_") for k in d)
    n = len(d["world_pos"])
    c = tf.constant
    ids = [np.arange(n)] + [d[f"pool_{i}"] for i in range(levels)]
    gs = [d["mesh_edges"]] + [d[f"level_edges_{i}"] for i in range(levels)]
    rng = np.random.default_rng(0)
    inputs = {
        "world_pos": c(d["world_pos"]),
        "prev|world_pos": c(d["world_pos"] - d["velocity"]),
        "mesh_pos": c(d["mesh_pos"]),
        "node_type": c(d["node_type"][:, None]),
        "density": c(d["density"]),
        "modulus": c(d["modulus"]),
        "cells": c(d["cells"]),
        "target|world_pos": c(d["world_pos"] + 0.01 * rng.normal(size=(n, 2)).astype(np.float32)),
        "target|stress": c(rng.normal(size=(n, 1)).astype(np.float32)),
        "m_ids": [c(i.astype(np.int32)) for i in ids],
        "m_gs_s": [c(e[0].astype(np.int32)) for e in gs],
        "m_gs_r": [c(e[1].astype(np.int32)) for e in gs],
    }
    edges = {
        "m_senders": c(d["mesh_edges"][0].astype(np.int32)),
        "m_receivers": c(d["mesh_edges"][1].astype(np.int32)),
        "c_senders": c(d["contact_edges"][0].astype(np.int32)),
        "c_receivers": c(d["contact_edges"][1].astype(np.int32)),
    }

    class GivenEdges(ImpactModel):
        def _build_graph(self, inputs, is_training):
            velocity = inputs["world_pos"] - inputs["prev|world_pos"]
            node_type = tf.one_hot(inputs["node_type"][:, 0], NodeType.SIZE)
            feats = tf.concat([velocity, node_type, inputs["density"], inputs["modulus"]], axis=-1)
            return self._node_normalizer(feats, is_training), inputs, edges

    model = GivenEdges(HCMT())
    optimizer = tf.keras.optimizers.Adam(learning_rate=1e-4)

    @tf.function
    def train_step():
        with tf.GradientTape() as tape:
            loss = model.loss(inputs)
        grads = tape.gradient(loss, model.trainable_variables)
        optimizer.apply_gradients(zip(grads, model.trainable_variables))
        return loss

    @tf.function
    def forward():
        return model(inputs)

    def train():
        train_step().numpy()

    def infer():
        forward()[0].numpy()

    info = {
        "framework": f"authors' HCMT (TensorFlow {tf.__version__})",
        "model": "hcmt",
        "mode": "tf.function",
        "nodes": n,
    }
    warm_up(info, train, infer)  # no FLOP count: credited with hcmt official HCMT's (run.FLOP_SOURCE)
    info["parameters"] = int(sum(np.prod(v.shape) for v in model.trainable_variables))
    return train, infer, info


if __name__ == "__main__":
    serve(*contestant(*sys.argv[1:3]))
