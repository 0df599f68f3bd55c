"""Trace a kernel on symbols: constant folding of exact identities, hash-consed CSE, op counts."""
import collections
import numpy as np

NODES = []          # (op, args)
INDEX = {}

def node(op, *args):
    key = (op,) + tuple(a.i if isinstance(a, Sym) else ('c', a) for a in args)
    if key in INDEX:
        return Sym(INDEX[key])
    NODES.append((op, args))
    INDEX[key] = len(NODES) - 1
    return Sym(len(NODES) - 1)

def reset():
    NODES.clear(); INDEX.clear()

def isnum(x):
    return isinstance(x, (float, int, np.floating))

class Sym:
    __slots__ = ("i",)
    __array_priority__ = 1000
    def __init__(self, i): self.i = i
    def __add__(a, b):
        if isnum(b) and b == 0: return a
        return node('add', a, b)
    def __radd__(a, b):
        if isnum(b) and b == 0: return a
        return node('add', b, a)
    def __sub__(a, b):
        if isnum(b) and b == 0: return a
        return node('sub', a, b)
    def __rsub__(a, b):
        if isnum(b) and b == 0: return -a
        return node('sub', b, a)
    def __mul__(a, b):
        if isnum(b):
            if b == 0: return 0.0
            if b == 1: return a
            if b == -1: return -a
        return node('mul', a, b)
    def __rmul__(a, b):
        if isnum(b):
            if b == 0: return 0.0
            if b == 1: return a
            if b == -1: return -a
        return node('mul', b, a)
    def __truediv__(a, b):
        if isnum(b) and b == 1: return a
        return node('div', a, b)
    def __rtruediv__(a, b):
        if isnum(b) and b == 0: return 0.0
        return node('div', b, a)
    def __neg__(a):
        op, args = NODES[a.i]
        if op == 'neg': return args[0]
        return node('neg', a)
    def __array_ufunc__(self, ufunc, method, *inputs, **kw):
        if ufunc is np.sqrt: return node('sqrt', *inputs)
        if ufunc is np.maximum: return node('max', *inputs)
        raise NotImplementedError(ufunc)

def sym_sincos(x):
    if isnum(x):
        return (np.sin(x), np.cos(x))
    return node('sin', x), node('cos', x)

def live(outputs):
    """indices of nodes reachable from outputs"""
    seen = set(); stack = [o.i for o in outputs if isinstance(o, Sym)]
    while stack:
        i = stack.pop()
        if i in seen: continue
        seen.add(i)
        for a in NODES[i][1]:
            if isinstance(a, Sym): stack.append(a.i)
    return seen

def counts(outputs):
    c = collections.Counter(NODES[i][0] for i in live(outputs))
    return dict(c)
