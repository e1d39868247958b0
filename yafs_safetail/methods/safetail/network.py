"""The Keras FNN of §III, process-wide determinism, and the NumPy fast path for decisions."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import numpy as np

from yafs_safetail.methods.objectives import Objective, objective_named
from yafs_safetail.methods.safetail.presets import LearnerConfig


def enable_determinism(seed: int) -> None:
    """Seed Keras/TensorFlow and turn TensorFlow's op determinism on.

    Both are process-global: ``keras.utils.set_random_seed`` also seeds Python's ``random``
    and NumPy's legacy global generator (this project never draws from either; the learner's
    own randomness comes from explicit generators and explicit initializer seeds), and op
    determinism, once on, stays on for the whole process (TensorFlow offers no way back). It
    is safe to call again with another seed: a learner's results do not depend on it.
    """
    import keras
    import tensorflow as tf

    keras.utils.set_random_seed(int(seed))
    tf.config.experimental.enable_op_determinism()


def build_network(
    state_dim: int, n_actions: int, config: LearnerConfig, init_seed: int
) -> Any:
    """Build and compile the policy FNN.

    ``state_dim`` inputs, one ReLU Dense layer per entry of ``config.hidden_widths``, a Dense
    layer over ``n_actions`` and Adam(``config.learning_rate``). The objective gives the last
    layer's activation and the loss (``Objective.output_activation``, ``compile_loss``): §III's
    target vector a softmax fitted by categorical cross-entropy; ``"value"`` a linear layer, each
    output the expected value of what an action is given to learn, fitted by
    :func:`masked_squared_error` (only the action taken has a target).
    Each layer's Glorot-uniform initializer gets its own seed derived from ``init_seed``, so
    the initial weights do not depend on any global random state.

    With ``config.n_networks`` = K > 1 (an objective that averages networks) the model holds K such networks
    side by side on the same input (layers ``net<j>_hidden<k>``, ``net<j>_actions``), each
    with its own initial weights, and outputs their K·``n_actions`` predictions concatenated
    (``actions``): one optimizer and one training call fit them all, each on its own error
    (:func:`masked_squared_error` sums over the entries). :func:`fast_forward` averages them.

    Returns:
        The compiled ``keras.Model``.
    """
    import keras

    n_networks = config.n_networks
    n_layers = len(config.hidden_widths) + 1
    layer_seeds = np.random.SeedSequence(init_seed).generate_state(n_networks * n_layers)
    objective = config.learning_objective

    def dense_stack(prefix: str, seeds: np.ndarray) -> list[Any]:
        stack = [
            keras.layers.Dense(
                width,
                activation="relu",
                kernel_initializer=keras.initializers.GlorotUniform(seed=int(seeds[k])),
                name=f"{prefix}hidden{k}",
            )
            for k, width in enumerate(config.hidden_widths)
        ]
        stack.append(
            keras.layers.Dense(
                n_actions,
                activation=objective.output_activation,
                kernel_initializer=keras.initializers.GlorotUniform(seed=int(seeds[-1])),
                name=f"{prefix}actions",
            )
        )
        return stack

    # Every object is named explicitly: Keras's automatic names get a per-process counter
    # ("adam_1", "input_layer_2"), which would make saved policies differ between two runs
    # in one process.
    state = keras.Input(shape=(state_dim,), dtype="float32", name="state")
    if n_networks == 1:
        model = keras.Sequential([state, *dense_stack("", layer_seeds)], name="safetail_fnn")
    else:
        outputs = []
        for j in range(n_networks):
            h = state
            for layer in dense_stack(f"net{j}_", layer_seeds[j * n_layers:(j + 1) * n_layers]):
                h = layer(h)
            outputs.append(h)
        joined = keras.layers.Concatenate(axis=-1, name="actions")(outputs)
        model = keras.Model(inputs=state, outputs=joined, name="safetail_fnn_ensemble")
    # No XLA: avoids a compile step per input shape (partial last batches) and keeps training
    # on the plain, op-deterministic kernels.
    model.compile(
        optimizer=keras.optimizers.Adam(learning_rate=config.learning_rate, name="adam"),
        loss=objective.compile_loss(),
        jit_compile=False,
    )
    # Build Adam's slots now so that a policy saved before its first round reloads cleanly.
    model.optimizer.build(model.trainable_variables)
    return model


@functools.cache
def masked_squared_error() -> Any:
    """The ``"value"`` objective's loss, registered with Keras so that saved policies reload.

    Squared error on the entries of ``y_true`` that are finite (the action taken; the others
    are NaN), summed per row: a value network learns only from the action it tried. Built on
    first use, so that importing this module does not load TensorFlow.
    """
    import keras
    import tensorflow as tf

    @keras.saving.register_keras_serializable(package="yafs_safetail", name="masked_squared_error")
    def loss(y_true: Any, y_pred: Any) -> Any:
        known = tf.math.is_finite(y_true)
        error = tf.where(known, y_pred - tf.where(known, y_true, 0.0), 0.0)
        return tf.reduce_sum(tf.square(error), axis=-1)

    return loss


def make_round_updates(model: Any, objective: Objective | str = "target-vector", jit_compile: bool = False) -> Any:
    """A function running a whole training round of minibatch Adam updates in one TensorFlow
    graph call.

    ``update(states, targets, batches)`` makes one update per row of ``batches`` (an integer
    array of shape (updates, batch size) indexing ``states`` and ``targets``), in order, with
    the objective's loss (an :class:`~yafs_safetail.methods.objectives.Objective` or its
    name; the one :func:`build_network` compiles) and the model's optimizer,
    and returns the mean loss. One graph call per round instead of one Keras call per
    minibatch: Keras's per-call overhead (milliseconds) is many times the arithmetic of this
    small network. ``jit_compile=True`` compiles the round with XLA: about a third faster, but
    the trained weights differ in their last bits, and so would every results file
    (``benchmarks/bench_training_round.py``); runs never use it.
    """
    import tensorflow as tf

    # Every learner traces its own round function; a process that builds several learners (a
    # calibration, the test suite) would otherwise get TensorFlow's retracing warning, which
    # is expected here and says nothing about the run.
    tf.get_logger().setLevel("ERROR")
    # The same loss build_network compiles the model with.
    loss_fn = (objective_named(objective) if isinstance(objective, str) else objective).round_loss()
    optimizer = model.optimizer
    variables = model.trainable_variables

    @tf.function(reduce_retracing=True, jit_compile=jit_compile)
    def run(states, targets, batches):
        total = tf.constant(0.0)
        n_updates = tf.shape(batches)[0]
        for i in tf.range(n_updates):
            x = tf.gather(states, batches[i])
            y = tf.gather(targets, batches[i])
            with tf.GradientTape() as tape:
                loss = tf.reduce_mean(loss_fn(y, model(x, training=True)))
            optimizer.apply(tape.gradient(loss, variables), variables)
            total += loss
        return total / tf.cast(n_updates, tf.float32)

    def update(states: np.ndarray, targets: np.ndarray, batches: np.ndarray) -> float:
        return float(run(tf.constant(states), tf.constant(targets),
                         tf.constant(batches.astype(np.int32))))

    return update


def _layer(inputs: np.ndarray, kernel: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """``inputs @ kernel + bias`` in float32, summed in one fixed order on every processor.

    A BLAS matrix product (NumPy's ``@``) sums in the order of the kernel its library picks for
    the processor, so two processors may round a near-tie between two subsets apart. Here each
    product is rounded once (an elementwise multiply) and the products are added input by input
    along the reduced axis (NumPy adds along a non-contiguous axis element by element, in
    order), so the result depends on the numbers alone. It also makes a batch's row equal the
    single state's output. About 3x the time of ``@`` on this network (tens of µs a decision).
    """
    products = inputs[..., :, np.newaxis] * kernel
    out = np.add.reduce(products, axis=-2)
    out += bias
    return out


class NumpyForward:
    """The FNN's forward pass in NumPy (float32), for one decision at a time.

    Keras's per-call overhead (``model(x)``: hundreds of µs; ``model.predict``: tens of ms)
    dwarfs the arithmetic of this small network. The last layer's softmax is skipped:
    it preserves the order of the logits, so the argmax is the same action. The sums take one
    order on every processor (:func:`_layer`), so a decision does not depend on NumPy's BLAS.
    """

    __slots__ = ("_hidden", "_out_bias", "_out_kernel")

    def __init__(self, weights: Sequence[np.ndarray]) -> None:
        """Args:
        weights: ``model.get_weights()`` of a network from :func:`build_network`:
            kernel, bias per layer, the last pair being the output layer.

        Raises:
            ValueError: an odd number of arrays or mismatched shapes.
        """
        if len(weights) < 2 or len(weights) % 2:
            raise ValueError(f"expected kernel/bias pairs, got {len(weights)} arrays")
        pairs = [
            (np.ascontiguousarray(weights[i], dtype=np.float32),
             np.ascontiguousarray(weights[i + 1], dtype=np.float32))
            for i in range(0, len(weights), 2)
        ]
        for k, (kernel, bias) in enumerate(pairs):
            if kernel.ndim != 2 or bias.shape != (kernel.shape[1],):
                raise ValueError(f"layer {k}: kernel {kernel.shape} and bias {bias.shape} mismatch")
            if k and kernel.shape[0] != pairs[k - 1][0].shape[1]:
                raise ValueError(f"layer {k}: input width {kernel.shape[0]} does not match")
        self._hidden = pairs[:-1]
        self._out_kernel, self._out_bias = pairs[-1]

    @classmethod
    def from_model(cls, model: Any) -> NumpyForward:
        """Copy the current weights of a Keras model built by :func:`build_network`."""
        return cls(model.get_weights())

    def logits(self, states: np.ndarray) -> np.ndarray:
        """Pre-softmax outputs for a state (shape (d,)) or a batch (shape (m, d))."""
        h = np.asarray(states, dtype=np.float32)
        for kernel, bias in self._hidden:
            h = _layer(h, kernel, bias)
            np.maximum(h, 0.0, out=h)
        return _layer(h, self._out_kernel, self._out_bias)

    def best_action(self, state: np.ndarray) -> int:
        """argmax over actions for one float32 state of shape (d,)."""
        return int(self.logits(state).argmax())


class EnsembleForward:
    """The mean of several :class:`NumpyForward` networks' outputs (``n_networks`` > 1)."""

    __slots__ = ("_members",)

    def __init__(self, members: Sequence[NumpyForward]) -> None:
        if not members:
            raise ValueError("an ensemble needs at least one network")
        self._members = tuple(members)

    def logits(self, states: np.ndarray) -> np.ndarray:
        """The members' mean output for a state (shape (d,)) or a batch (shape (m, d))."""
        total = self._members[0].logits(states)
        for member in self._members[1:]:
            total += member.logits(states)
        total /= len(self._members)
        return total

    def best_action(self, state: np.ndarray) -> int:
        """argmax of the mean output for one float32 state of shape (d,)."""
        return int(self.logits(state).argmax())


def fast_forward(model: Any, config: LearnerConfig) -> NumpyForward | EnsembleForward:
    """The NumPy forward pass of a network from :func:`build_network` with ``config``: the
    network itself, or the mean of its ``config.n_networks`` members."""
    if config.n_networks == 1:
        return NumpyForward.from_model(model)
    n_hidden = len(config.hidden_widths)
    members = []
    for j in range(config.n_networks):
        names = [f"net{j}_hidden{k}" for k in range(n_hidden)] + [f"net{j}_actions"]
        members.append(NumpyForward([w for name in names for w in model.get_layer(name).get_weights()]))
    return EnsembleForward(members)
