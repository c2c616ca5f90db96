"""The constants (weights) of a frozen TensorFlow graph (`GraphDef` protobuf, `.pb`), read
without TensorFlow: the message types the file needs (GraphDef, NodeDef, AttrValue,
TensorProto, TensorShapeProto) are declared here at run time from TensorFlow's published
field numbers and parsed by the `protobuf` package.

Used to load the COCO-trained SSD-MobileNetV2 detector's weights into the torch port of
:mod:`usvfast.shore.ssd` (OpenCV 5 no longer reads TensorFlow graphs).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: TensorFlow DataType enum values read here -> numpy dtypes.
_DTYPES = {1: np.float32, 2: np.float64, 3: np.int32, 4: np.uint8, 9: np.int64, 10: np.bool_}


def _message_classes():
    """GraphDef and its nested messages, declared from TensorFlow's field numbers."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    F = descriptor_pb2.FieldDescriptorProto
    fd = descriptor_pb2.FileDescriptorProto(name="usvfast_tfgraph.proto", package="usvfast_tf")

    def msg(name: str, fields: list[tuple]) -> None:
        m = fd.message_type.add(name=name)
        for fname, number, ftype, label, type_name in fields:
            f = m.field.add(name=fname, number=number, type=ftype, label=label)
            if type_name:
                f.type_name = f".usvfast_tf.{type_name}"

    opt, rep = F.LABEL_OPTIONAL, F.LABEL_REPEATED
    msg("Dim", [("size", 1, F.TYPE_INT64, opt, None), ("name", 2, F.TYPE_STRING, opt, None)])
    msg(
        "TensorShapeProto",
        [("dim", 2, F.TYPE_MESSAGE, rep, "Dim"), ("unknown_rank", 3, F.TYPE_BOOL, opt, None)],
    )
    msg(
        "TensorProto",
        [
            ("dtype", 1, F.TYPE_INT32, opt, None),  # DataType enum: varint on the wire
            ("tensor_shape", 2, F.TYPE_MESSAGE, opt, "TensorShapeProto"),
            ("tensor_content", 4, F.TYPE_BYTES, opt, None),
            ("float_val", 5, F.TYPE_FLOAT, rep, None),
            ("double_val", 6, F.TYPE_DOUBLE, rep, None),
            ("int_val", 7, F.TYPE_INT32, rep, None),
            ("int64_val", 10, F.TYPE_INT64, rep, None),
            ("bool_val", 11, F.TYPE_BOOL, rep, None),
        ],
    )
    msg(
        "ListValue",
        [
            ("s", 2, F.TYPE_BYTES, rep, None),
            ("i", 3, F.TYPE_INT64, rep, None),
            ("f", 4, F.TYPE_FLOAT, rep, None),
            ("b", 5, F.TYPE_BOOL, rep, None),
        ],
    )
    msg(
        "AttrValue",
        [
            ("list", 1, F.TYPE_MESSAGE, opt, "ListValue"),
            ("s", 2, F.TYPE_BYTES, opt, None),
            ("i", 3, F.TYPE_INT64, opt, None),
            ("f", 4, F.TYPE_FLOAT, opt, None),
            ("b", 5, F.TYPE_BOOL, opt, None),
            ("type", 6, F.TYPE_INT32, opt, None),
            ("tensor", 8, F.TYPE_MESSAGE, opt, "TensorProto"),
        ],
    )
    msg("AttrEntry", [("key", 1, F.TYPE_STRING, opt, None)])
    entry = fd.message_type[-1]
    f = entry.field.add(name="value", number=2, type=F.TYPE_MESSAGE, label=opt)
    f.type_name = ".usvfast_tf.AttrValue"
    msg(
        "NodeDef",
        [
            ("name", 1, F.TYPE_STRING, opt, None),
            ("op", 2, F.TYPE_STRING, opt, None),
            ("input", 3, F.TYPE_STRING, rep, None),
            ("attr", 5, F.TYPE_MESSAGE, rep, "AttrEntry"),
        ],
    )
    msg("GraphDef", [("node", 1, F.TYPE_MESSAGE, rep, "NodeDef")])
    pool = descriptor_pool.DescriptorPool()
    pool.Add(fd)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName("usvfast_tf.GraphDef"))


@dataclass(frozen=True)
class GraphNode:
    """One node of the graph: `name`, `op`, `inputs` (node names, ':k' outputs kept) and
    `attrs` (its scalar and integer-list attributes: strides, padding, ...; tensors left out)."""

    name: str
    op: str
    inputs: tuple[str, ...]
    attrs: dict


def _attr(v):
    """A scalar or list attribute's Python value (None for tensors and others)."""
    for f in ("s", "i", "f", "b"):
        if v.HasField(f):
            x = getattr(v, f)
            return x.decode("utf-8", "replace") if f == "s" else x
    if v.HasField("list"):
        return list(v.list.i) or list(v.list.f) or [s.decode() for s in v.list.s]
    return None


def _tensor(t) -> np.ndarray | None:
    """The array of a TensorProto; None for dtypes not read here (strings, ...)."""
    dtype = _DTYPES.get(t.dtype)
    if dtype is None:
        return None
    shape = tuple(int(d.size) for d in t.tensor_shape.dim)
    if t.tensor_content:
        return np.frombuffer(t.tensor_content, dtype=dtype).reshape(shape).copy()
    vals = {
        np.float32: t.float_val,
        np.float64: t.double_val,
        np.int32: t.int_val,
        np.uint8: t.int_val,
        np.int64: t.int64_val,
        np.bool_: t.bool_val,
    }[dtype]
    a = np.asarray(list(vals), dtype=dtype)
    n = int(np.prod(shape)) if shape else 1
    if a.size == n:
        return a.reshape(shape)
    if a.size == 1:  # TensorFlow stores a constant-filled tensor as its one value
        return np.full(shape, a[0], dtype=dtype)
    raise ValueError(f"graph: constant holds {a.size} values for shape {shape}")


@dataclass
class FrozenGraph:
    """A frozen graph's `nodes` (in file order) and `constants` (name -> array of every
    numeric `Const` node; string constants are left out)."""

    nodes: list[GraphNode]
    constants: dict[str, np.ndarray]

    def node(self, name: str) -> GraphNode:
        """The node called `name`; KeyError naming it when absent."""
        if not hasattr(self, "_by_name"):
            self._by_name = {n.name: n for n in self.nodes}
        try:
            return self._by_name[name]
        except KeyError:
            raise KeyError(f"graph: no node {name!r}") from None

    @classmethod
    def read(cls, path: Path | str) -> FrozenGraph:
        """Parse a frozen `.pb` file. Raises ValueError naming `path` when it is missing or
        not a GraphDef."""
        path = Path(path)
        if not path.is_file():
            raise ValueError(f"path: no such graph file {path}")
        from google.protobuf.message import DecodeError

        g = _message_classes()()
        try:
            g.ParseFromString(path.read_bytes())
        except DecodeError as e:
            raise ValueError(f"path: {path} is not a TensorFlow GraphDef ({e})") from None
        # the message class is declared at run time: its fields are unknown to type checkers
        graph_nodes = g.node  # pyright: ignore[reportAttributeAccessIssue]
        if not len(graph_nodes):
            raise ValueError(f"path: {path} holds no graph nodes")
        nodes, consts = [], {}
        for n in graph_nodes:
            attrs = {a.key: _attr(a.value) for a in n.attr if a.key != "value"}
            nodes.append(GraphNode(n.name, n.op, tuple(n.input), attrs))
            if n.op == "Const":
                for a in n.attr:
                    if a.key == "value" and (v := _tensor(a.value.tensor)) is not None:
                        consts[n.name] = v
        return cls(nodes, consts)
