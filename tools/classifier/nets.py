"""The two networks, trained with numpy: ours (an MLP with a softmax over the classes, sized by
validation) and the paper's (section 2.3: 9 inputs scaled to [0, 1], 9 sigmoid hidden units, 4
sigmoid outputs that binary-code the class, 0000 .. 1011 for our 12).

numpy is enough: ten thousand samples, nets of a few thousand weights, and full control of the
seed; a deep-learning library would add hundreds of megabytes for nothing. Training is Adam
(Kingma and Ba 2015) on mini-batches with a cosine learning-rate schedule; the epoch with the best
validation accuracy is kept. (Early stopping on the validation loss was tried: it stops while the
class boundaries are still soft, 1-2 points of accuracy lower on the same data.)
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

LEARNING_RATE = 3e-3  # at the start of the cosine schedule
PAPER_LEARNING_RATE = 1e-2  # the paper's sigmoid net learns slowly: measured best of 3e-3, 1e-2, 3e-2 (within 2 points)
WEIGHT_DECAY = 1e-5  # L2 on the weights, added to the gradient of the mean loss
BATCH = 128
EPOCHS = 150  # passes over the training pushes and their mirror images: 300 passes' steps over the pushes alone
HIDDEN_CHOICES: tuple[tuple[int, ...], ...] = ((16,), (32, 32), (64, 64))
PAPER_HIDDEN = 9
PAPER_BITS = 4


@dataclass
class Net:
    """A fully connected net: weights[k] (in, out), biases[k] (out,). Hidden layers use
    `hidden_activation` (tanh for ours, sigmoid for the paper's); the last layer's activation is
    `output` ("softmax" for ours, "sigmoid" for the paper's). Inputs are normalised as
    (x - mean) / scale first."""

    weights: list[np.ndarray]
    biases: list[np.ndarray]
    mean: np.ndarray
    scale: np.ndarray
    output: str = "softmax"
    hidden_activation: str = "tanh"

    @property
    def hidden(self) -> tuple[int, ...]:
        return tuple(w.shape[1] for w in self.weights[:-1])

    @property
    def parameter_count(self) -> int:
        return int(sum(w.size + b.size for w, b in zip(self.weights, self.biases, strict=True)))

    def forward(self, x: np.ndarray) -> list[np.ndarray]:
        """Activations of every layer, the normalised input first."""
        layers = [(x - self.mean) / self.scale]
        for k, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            last = k == len(self.weights) - 1
            layers.append(_activate(layers[-1] @ w + b, self.output if last else self.hidden_activation))
        return layers

    def outputs(self, x: np.ndarray) -> np.ndarray:
        return self.forward(x)[-1]


def _activate(z: np.ndarray, kind: str) -> np.ndarray:
    if kind == "softmax":
        e = np.exp(z - z.max(axis=1, keepdims=True))
        return e / e.sum(axis=1, keepdims=True)
    if kind == "sigmoid":
        return 1.0 / (1.0 + np.exp(-z))
    return np.tanh(z)


def _slope(activation: np.ndarray, kind: str) -> np.ndarray:
    """The hidden activation's derivative, from its value."""
    return activation * (1.0 - activation) if kind == "sigmoid" else 1.0 - activation**2


def _init(sizes: list[int], rng: np.random.Generator) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Glorot-uniform weights, zero biases."""
    weights = [rng.uniform(-1.0, 1.0, (a, b)) * np.sqrt(6.0 / (a + b)) for a, b in itertools.pairwise(sizes)]
    return weights, [np.zeros(b) for b in sizes[1:]]


def _gradients(net: Net, x: np.ndarray, target: np.ndarray) -> list[np.ndarray]:
    """Backpropagation of the mean cross-entropy (softmax) or binary cross-entropy per bit
    (sigmoid outputs), whose gradient at the last pre-activation is (output - target) / N in both
    cases; plus weight decay. Weights' gradients first, then the biases'."""
    layers = net.forward(x)
    delta = (layers[-1] - target) / len(x)
    grad_w, grad_b = [], []
    for k in range(len(net.weights) - 1, -1, -1):
        grad_w.append(layers[k].T @ delta + WEIGHT_DECAY * net.weights[k])
        grad_b.append(delta.sum(axis=0))
        if k:
            delta = (delta @ net.weights[k].T) * _slope(layers[k], net.hidden_activation)
    return grad_w[::-1] + grad_b[::-1]


class _Adam:
    """Adam's moment estimates for a list of parameter arrays, updated in place."""

    def __init__(self, params: list[np.ndarray]):
        self.params = params
        self.first = [np.zeros_like(p) for p in params]
        self.second = [np.zeros_like(p) for p in params]
        self.steps = 0

    def step(self, grads: list[np.ndarray], rate: float) -> None:
        beta1, beta2, eps = 0.9, 0.999, 1e-8
        self.steps += 1
        for p, g, m, v in zip(self.params, grads, self.first, self.second, strict=True):
            m *= beta1
            m += (1.0 - beta1) * g
            v *= beta2
            v += (1.0 - beta2) * g * g
            p -= rate * (m / (1.0 - beta1**self.steps)) / (np.sqrt(v / (1.0 - beta2**self.steps)) + eps)


@dataclass
class Split:
    """Inputs (N, F), targets (N, K) (one-hot classes or code bits) and class indices (N,)."""

    x: np.ndarray
    target: np.ndarray
    labels: np.ndarray


def train(
    net: Net,
    train_split: Split,
    val_split: Split,
    predict: Callable[[Net, np.ndarray], np.ndarray],
    seed: int,
    epochs: int = EPOCHS,
    rate: float = LEARNING_RATE,
) -> Net:
    """Adam on mini-batches, cosine schedule; returns the weights of the best validation epoch."""
    rng = np.random.default_rng(seed)
    params = net.weights + net.biases
    adam = _Adam(params)
    best_accuracy, best = -1.0, [p.copy() for p in params]
    for epoch in range(epochs):
        scheduled = rate * 0.5 * (1.0 + np.cos(np.pi * epoch / epochs))
        order = rng.permutation(len(train_split.x))
        for start in range(0, len(order), BATCH):
            batch = order[start : start + BATCH]
            adam.step(_gradients(net, train_split.x[batch], train_split.target[batch]), scheduled)
        accuracy = float(np.mean(predict(net, val_split.x) == val_split.labels))
        if accuracy >= best_accuracy:
            best_accuracy, best = accuracy, [p.copy() for p in params]
    layers = len(net.weights)
    return Net(best[:layers], best[layers:], net.mean, net.scale, net.output, net.hidden_activation)


# ---------------------------------------------------------------------------------------------
# Ours: softmax over the classes, sized by validation


def standardiser(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and spread of the training inputs (a constant column gets spread 1)."""
    scale = x.std(axis=0)
    return x.mean(axis=0), np.where(scale > 1e-9, scale, 1.0)


def predict_softmax(net: Net, x: np.ndarray) -> np.ndarray:
    return np.argmax(net.outputs(x), axis=1)


def fit_softmax(
    train_x: np.ndarray,
    train_y: np.ndarray,
    val_x: np.ndarray,
    val_y: np.ndarray,
    classes: int,
    hidden: tuple[int, ...],
    seed: int,
    epochs: int = EPOCHS,
) -> Net:
    """Our MLP with the given hidden layers (tanh) over `classes` softmax outputs."""
    mean, scale = standardiser(train_x)
    weights, biases = _init([train_x.shape[1], *hidden, classes], np.random.default_rng(seed))
    eye = np.eye(classes)
    return train(
        Net(weights, biases, mean, scale),
        Split(train_x, eye[train_y], train_y),
        Split(val_x, eye[val_y], val_y),
        predict_softmax,
        seed,
        epochs,
    )


@dataclass
class SizeTrial:
    """One hidden size tried: its parameter count, validation accuracy (classes, and direction
    groups), and the trained net."""

    hidden: tuple[int, ...]
    parameters: int
    val_accuracy: float
    val_group_accuracy: float
    net: Net


def choose_size(
    train_x: np.ndarray,
    train_y: np.ndarray,
    val_x: np.ndarray,
    val_y: np.ndarray,
    classes: int,
    seed: int,
    choices: tuple[tuple[int, ...], ...] = HIDDEN_CHOICES,
    epochs: int = EPOCHS,
    progress: Callable[[SizeTrial], None] | None = None,
    groups: np.ndarray | None = None,
) -> tuple[SizeTrial, list[SizeTrial]]:
    """Train every hidden size; the best validation accuracy on the direction groups wins (groups:
    class index -> group index; a wrong direction is the miss an animator sees, a roll for a fall
    on the hands a lesser one), then on the classes, then the smaller net (ties within one
    validation sample)."""
    group_of = np.arange(classes) if groups is None else np.asarray(groups)
    trials = []
    for hidden in choices:
        net = fit_softmax(train_x, train_y, val_x, val_y, classes, hidden, seed, epochs)
        predicted = predict_softmax(net, val_x)
        accuracy = float(np.mean(predicted == val_y))
        group_accuracy = float(np.mean(group_of[predicted] == group_of[val_y]))
        trials.append(SizeTrial(hidden, net.parameter_count, accuracy, group_accuracy, net))
        if progress:
            progress(trials[-1])
    step = 1.0 / max(len(val_y), 1)
    best = max(trials, key=lambda t: (round(t.val_group_accuracy / step), round(t.val_accuracy / step), -t.parameters))
    return best, trials


# ---------------------------------------------------------------------------------------------
# The paper's 9-9-4 sigmoid network with binary-coded classes


def class_bits(labels: np.ndarray) -> np.ndarray:
    """Class index -> 4 bits, most significant first (class 9 = 1001)."""
    return ((labels[:, None] >> np.arange(PAPER_BITS - 1, -1, -1)) & 1).astype(float)


def predict_paper(net: Net, x: np.ndarray, count: int) -> np.ndarray:
    """Decoded class indices of `count` classes; a code past the last class decodes to -1 (wrong)."""
    bits = (net.outputs(x) > 0.5).astype(int)
    index = bits @ (1 << np.arange(PAPER_BITS - 1, -1, -1))
    return np.where(index < count, index, -1)


def fit_paper(
    training: tuple[np.ndarray, np.ndarray],
    validation: tuple[np.ndarray, np.ndarray],
    count: int,
    seed: int,
    epochs: int = EPOCHS,
) -> Net:
    """The paper's net on (x, y) splits of `count` classes: inputs scaled to [0, 1] by the training
    set's range, 9 sigmoid hidden units, 4 sigmoid outputs; twice the epochs of ours (it is 130
    weights: cheap, and slow to learn)."""
    (train_x, train_y), (val_x, val_y) = training, validation
    low, high = train_x.min(axis=0), train_x.max(axis=0)
    scale = np.where(high - low > 1e-9, high - low, 1.0)
    weights, biases = _init([train_x.shape[1], PAPER_HIDDEN, PAPER_BITS], np.random.default_rng(seed))
    net = Net(weights, biases, low, scale, output="sigmoid", hidden_activation="sigmoid")
    return train(
        net,
        Split(train_x, class_bits(train_y), train_y),
        Split(val_x, class_bits(val_y), val_y),
        lambda n, x: predict_paper(n, x, count),
        seed,
        2 * epochs,
        PAPER_LEARNING_RATE,
    )
