"""The model's and the controller laws' Python text translated to C99: one translator for every export.

The compiled model is generated Python text (:mod:`ehas_env.physics.codegen`: the baseline, each effect's terms,
the controller laws, the assembled right-hand side and the one RK4 integrator).  That text is written in a small
subset of Python -- numbers, ``math``, ``if``/``elif``/``else``, ``for ... in range``, ``while``, one-dimensional
``float64`` arrays read and written element by element, functions returning a number or a tuple of numbers --
and :class:`CTranslator` turns the functions of such a text into C99, so the C an export writes
(``ehas export-controller --format c``, ``ehas export-fmu``) is generated from the very text numba compiles: no
second hand-written copy of the physics or of a law.

Mapping (Python semantics kept where C differs):

* scalars are ``double`` unless every value a variable takes is an integer (``range`` loop counters, integer
  literals, ``int(...)``, ``len(...)``, ``x.shape[0]``: then ``long``); ``True``/``False`` and comparisons are
  ``long`` 0/1;
* ``/`` is always true division in ``double``; ``//`` and ``%`` floor as Python's do (``ehas_floordiv``,
  ``ehas_mod``); ``**`` is ``pow``; ``min``/``max`` keep Python's choice of the first of equal arguments;
  ``abs`` is ``fabs``/``labs``; ``math.degrees``/``radians`` multiply by numba's constant (``180 / pi``);
* an array argument ``x`` is ``double *x, long x_n`` (``x.shape[0]`` and ``len(x)`` are ``x_n``); ``x[:] = v``
  is a loop; a negative constant index counts from the end; one indexed ``x[i, j]`` is a row-major table,
  ``double *x, long x_n, long x_m`` (``x.shape[1]`` is ``x_m``); an argument that defaults to ``None`` is an
  array that may be left out (``NULL`` and 0; ``x is None`` and ``x is not None`` test it);
* arrays of the function's own -- ``np.zeros(n)``, ``np.empty(n)`` of a constant ``n``, ``np.zeros_like(a)``,
  ``np.empty_like(a)``, or a call of an *allocating helper* whose body returns a tuple of those (``rk4_work``) --
  are C99 arrays of the function (variable-length for an array's length); ``P = P.copy()`` copies an argument
  into such an array and points the argument at it; ``np.max(x)`` and ``np.min(x)`` of an array are loops;
* a function returning a tuple of ``n`` numbers takes ``n`` output pointers after its arguments; ``a, b = f()``,
  ``ds[4], ds[5] = f()``, ``f()[0]`` and ``r = f()`` (then ``r[j]``) are supported, every value computed
  before any is stored (as Python does);
* names of module constants (``N_STATES``, ``I_AREA``, ``A, B = 0, 1``, ...) are replaced by their values; every
  function is ``static`` and named ``<prefix><name>``.

Anything else (arrays of more than two dimensions, a row of a table passed on, closures, comprehensions,
strings) is refused with a :class:`TranslationError` naming the function and the line.  The replays' drivers
(``closed_loop``, ``run_valve_test``) translate whole (:mod:`ehas_env.physics.c_drivers`); an export writes its
own fixed-step driver around ``advance``.

Examples
--------
>>> from ehas_env.physics.c_source import translate
>>> print(translate("def f(x, y):\\n    return max(x, 2 * y) / 3\\n", ["f"]).strip().splitlines()[-1])
}
"""
from __future__ import annotations

import ast
import math
import numbers

#: C keywords and libc/libm names a Python local may not keep as its C name (it gets a trailing underscore)
_RESERVED = frozenset("""
auto break case char const continue default do double else enum extern float for goto if inline int long register
restrict return short signed sizeof static struct switch typedef union unsigned void volatile while _Bool _Complex
abs fabs div ldiv labs exp log log10 log2 pow sqrt cbrt sin cos tan asin acos atan atan2 sinh cosh tanh asinh acosh
atanh floor ceil round trunc fmod fmin fmax erf erfc gamma lgamma tgamma j0 j1 jn y0 y1 yn hypot copysign nan isnan
isinf isfinite signbit expm1 log1p frexp ldexp modf remainder rint lrint nearbyint scalbn time clock rand srand exit
abort free malloc calloc realloc index rindex errno stdin stdout stderr printf main select signal random M_PI NULL
""".split())

#: math.* functions mapped one to one onto C99's <math.h>
_MATH = {"sqrt": "sqrt", "sin": "sin", "cos": "cos", "tan": "tan", "asin": "asin", "acos": "acos", "atan": "atan",
         "atan2": "atan2", "exp": "exp", "log": "log", "log10": "log10", "log2": "log2", "log1p": "log1p",
         "expm1": "expm1", "tanh": "tanh", "sinh": "sinh", "cosh": "cosh", "copysign": "copysign",
         "floor": "floor", "ceil": "ceil", "fabs": "fabs", "hypot": "hypot", "erf": "erf", "erfc": "erfc",
         "pow": "pow", "trunc": "trunc", "fmod": "fmod", "atanh": "atanh", "asinh": "asinh", "acosh": "acosh"}

#: helpers every translated unit starts with (Python's floor division and modulo, min/max, the first-of-equal rule)
PRELUDE = r"""#include <math.h>
#include <stddef.h>

static inline double ehas_mod(double a, double b)
{   /* Python's a % b for floats: the sign of b */
    double m = fmod(a, b);
    if (m != 0.0) { if ((b < 0.0) != (m < 0.0)) m += b; }
    else m = copysign(0.0, b);
    return m;
}
static inline long ehas_imod(long a, long b) { long m = a % b; if (m != 0 && ((m < 0) != (b < 0))) m += b; return m; }
static inline double ehas_floordiv(double a, double b) { return floor(a / b); }
static inline long ehas_ifloordiv(long a, long b) { long q = a / b; if ((a % b != 0) && ((a < 0) != (b < 0))) q -= 1; return q; }
static inline double ehas_min(double a, double b) { return b < a ? b : a; }
static inline double ehas_max(double a, double b) { return b > a ? b : a; }
static inline long ehas_imin(long a, long b) { return b < a ? b : a; }
static inline long ehas_imax(long a, long b) { return b > a ? b : a; }
"""

INT, DBL, ARR = "long", "double", "array"


class TranslationError(ValueError):
    """A construct of the Python text outside the subset the translator knows (names the function and line)."""


def _num(value) -> str:
    """A C literal of a Python number that reads back as the same double (or integer)."""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    v = float(value)
    if math.isnan(v):
        return "NAN"
    if math.isinf(v):
        return "INFINITY" if v > 0 else "(-INFINITY)"
    text = repr(v)
    if "e" not in text and "." not in text:
        text += ".0"
    return f"({text})" if text.startswith("-") else text


def c_literal(value) -> str:
    """A C literal of a number, as the translator writes it: it reads back as the same double (or integer).

    Parameters
    ----------
    value : int, float or bool
        The number.

    Returns
    -------
    str
        The C literal (``NAN``, ``INFINITY`` for those; a negative one in parentheses).

    Examples
    --------
    >>> c_literal(0.1), c_literal(-2.0), c_literal(3)
    ('0.1', '(-2.0)', '3')
    """
    return _num(value)


def c_array(values, per_line: int = 0) -> str:
    """A C initializer ``{a, b, ...}`` of numbers as doubles (:func:`c_literal`); ``{0.0}`` when there are none
    (C has no empty initializer).

    Parameters
    ----------
    values : iterable of float
        The numbers.
    per_line : int
        Numbers per line (an indented block); 0: all on one line.

    Returns
    -------
    str
        The initializer.

    Examples
    --------
    >>> c_array([1, 0.5]), c_array([])
    ('{1.0, 0.5}', '{0.0}')
    """
    vals = [_num(float(v)) for v in values]
    if not vals:
        return "{0.0}"
    if per_line <= 0:
        return "{" + ", ".join(vals) + "}"
    lines = [", ".join(vals[i:i + per_line]) for i in range(0, len(vals), per_line)]
    return "{\n    " + ",\n    ".join(lines) + "\n}"


class _Func:
    """What the translator knows of one Python function: its parameters' kinds, its return and its locals."""

    def __init__(self, node: ast.FunctionDef):
        self.node = node
        self.name = node.name
        self.params = [a.arg for a in node.args.args]
        defaults = node.args.defaults
        #: why the function does not translate (raised when it is asked for, :meth:`CTranslator.closure`)
        self.refused = None
        if node.args.vararg or node.args.kwarg or node.args.kwonlyargs or node.args.posonlyargs:
            self.refused = f"{node.name} (line {node.lineno}): only plain positional arguments translate"
        elif any(not (isinstance(v, ast.Constant) and v.value is None) for v in defaults):
            self.refused = f"{node.name} (line {node.lineno}): a default other than None does not translate"
        # an argument that defaults to None is an array that may be left out: a NULL pointer of length 0
        self.optional: set[str] = set(self.params[len(self.params) - len(defaults):])
        self.arrays: set[str] = set(self.optional)  # array parameters
        self.arrays2d: set[str] = set()  # ... of those, the two-dimensional ones (row-major, ``x_m`` columns)
        self.ret = None  # None: nothing; INT / DBL: a number; int n: a tuple of n numbers
        self.locals: dict[str, object] = {}


class CTranslator:
    """Python functions of one module text -> C99 (see the module docstring for the subset).

    Parameters
    ----------
    text : str
        The Python module text (a generated model, a law's file).
    constants : dict, optional
        Names the functions read as constants (number values), besides the numeric assignments at the text's
        top level (those are read too).
    prefix : str
        Prefix of every C function's name.
    """

    def __init__(self, text: str, constants: dict | None = None, prefix: str = "ehas_"):
        self.tree = ast.parse(text)
        self.prefix = prefix
        self.consts: dict[str, object] = {k: v for k, v in (constants or {}).items()
                                          if isinstance(v, (numbers.Real, bool))}
        self.consts["math.pi"] = math.pi
        self.consts["math.e"] = math.e
        self.consts["math.inf"] = math.inf
        self.funcs: dict[str, _Func] = {}
        for node in self.tree.body:
            if isinstance(node, ast.FunctionDef):
                for inner in self._lift(node):
                    self.funcs[inner.name] = _Func(inner)
                self.funcs[node.name] = _Func(node)
            elif isinstance(node, ast.Assign) and len(node.targets) == 1:
                target = node.targets[0]
                pairs = ([(target, node.value)] if isinstance(target, ast.Name) else
                         list(zip(target.elts, node.value.elts))  # ``A, B = 0, 1``
                         if isinstance(target, ast.Tuple) and isinstance(node.value, ast.Tuple)
                         and len(target.elts) == len(node.value.elts) else [])
                for name, v in pairs:
                    try:
                        value = ast.literal_eval(v)
                    except (ValueError, SyntaxError, TypeError):
                        continue
                    if isinstance(name, ast.Name) and isinstance(value, (numbers.Real, bool)):
                        self.consts[name.id] = value

    @staticmethod
    def _lift(node: ast.FunctionDef) -> list:
        """Helper functions defined inside ``node`` (e.g. an effect term's ``root``), taken out as functions of
        their own named ``<outer>__<inner>`` (a helper that reads the outer function's variables then fails to
        translate with the name it reads)."""
        inner = [s for s in node.body if isinstance(s, ast.FunctionDef)]
        if not inner:
            return []
        names = {s.name: f"{node.name}__{s.name}" for s in inner}
        node.body = [s for s in node.body if not isinstance(s, ast.FunctionDef)]
        for s in inner:
            s.name = names[s.name]
        for n in ast.walk(node):
            if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id in names:
                n.func.id = names[n.func.id]
        return inner

    # -- which functions -------------------------------------------------------------------------
    def closure(self, roots) -> list[str]:
        """The functions ``roots`` call, directly or not, with the roots, in the text's order."""
        todo, seen = list(roots), set()
        while todo:
            name = todo.pop()
            if name in seen:
                continue
            if name not in self.funcs:
                raise TranslationError(f"no function {name!r} in the text")
            if self.funcs[name].refused:
                raise TranslationError(self.funcs[name].refused)
            seen.add(name)
            for n in ast.walk(self.funcs[name].node):
                if (isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id in self.funcs
                        and self.allocator(n) is None):
                    todo.append(n.func.id)
        return [n for n in self.funcs if n in seen]

    def allocator(self, call):
        """The allocations a call of an *allocating helper* stands for -- a function of the text whose body is
        ``return`` a tuple of allocations of its arguments (``rk4_work(s)``: five ``np.empty_like(s)``) --, with
        the call's arguments in place of the helper's (a list of expressions); None for any other call.  Such a
        call is not translated as a function: each target it is unpacked into becomes a local array."""
        if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Name) and call.func.id in self.funcs):
            return None
        f = self.funcs[call.func.id]
        body = [b for b in f.node.body if not (isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant))]
        if len(body) != 1 or not isinstance(body[0], ast.Return) or not isinstance(body[0].value, ast.Tuple):
            return None
        if not all(isinstance(a, ast.Name) for a in call.args) or len(call.args) != len(f.params):
            return None
        names = dict(zip(f.params, (a.id for a in call.args)))
        outs = []
        for el in body[0].value.elts:
            if not self._allocates(el):
                return None
            el = ast.fix_missing_locations(_Renamed(names).visit(ast.parse(ast.unparse(el), mode="eval").body))
            el.lineno = call.lineno
            outs.append(el)
        return outs

    # -- analysis ---------------------------------------------------------------------------------
    def analyse(self, roots) -> list[str]:
        """Type the functions ``roots`` and every function they call (what :meth:`translate` does before it writes
        C), so that :meth:`signature` answers without any C being written.

        Parameters
        ----------
        roots : sequence of str

        Returns
        -------
        list of str
            The functions analysed (:meth:`closure`).
        """
        names = self.closure(roots)
        self._analyse(names)
        return names

    def _analyse(self, names: list[str]) -> None:
        fs = [self.funcs[n] for n in names]
        for f in fs:
            for n in ast.walk(f.node):
                if isinstance(n, ast.Subscript) and isinstance(n.value, ast.Name) and n.value.id in f.params:
                    f.arrays.add(n.value.id)
                    if isinstance(n.slice, ast.Tuple):
                        f.arrays2d.add(n.value.id)
                if (isinstance(n, ast.Attribute) and n.attr in ("shape", "copy") and isinstance(n.value, ast.Name)
                        and n.value.id in f.params):
                    f.arrays.add(n.value.id)
        changed = True
        while changed:  # an argument passed where the callee takes an array is an array
            changed = False
            for f in fs:
                for n in ast.walk(f.node):
                    if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id in self.funcs:
                        callee = self.funcs[n.func.id]
                        for p, a in zip(callee.params, n.args):
                            if (p in callee.arrays and isinstance(a, ast.Name) and a.id in f.params
                                    and a.id not in f.arrays):
                                f.arrays.add(a.id)
                                changed = True
                            # and an array passed on is an array in the callee, used there or not
                            if (isinstance(a, ast.Name) and a.id in f.arrays and p not in callee.arrays):
                                callee.arrays.add(p)
                                changed = True
        changed = True
        while changed:  # return kinds (a function returning another's result takes its kind)
            changed = False
            for f in fs:
                kind = self._return_kind(f)
                if kind != f.ret:
                    f.ret, changed = kind, True
        for f in fs:
            self._locals(f)

    def _return_kind(self, f: _Func):
        kinds = []
        for n in ast.walk(f.node):
            if isinstance(n, ast.Return) and n.value is not None:
                v = n.value
                if isinstance(v, ast.Tuple):
                    kinds.append(len(v.elts))
                elif isinstance(v, ast.Call) and isinstance(v.func, ast.Name) and isinstance(
                        getattr(self.funcs.get(v.func.id), "ret", None), int):
                    kinds.append(self.funcs[v.func.id].ret)
                else:
                    kinds.append(self._etype(v, f, {}, loose=True))
        if not kinds:
            return None
        tuples = {k for k in kinds if isinstance(k, int)}
        if tuples:
            if len(tuples) > 1 or len(tuples) != len(set(kinds)):
                raise TranslationError(f"{f.name}: returns tuples of different lengths or a tuple and a number")
            return tuples.pop()
        return INT if all(k == INT for k in kinds) else DBL

    def _locals(self, f: _Func) -> None:
        """Each local's C type: long when every value assigned to it is an integer, a local array for a tuple."""
        assigns: list[tuple[str, ast.AST]] = []
        loops: set[str] = set()
        for n in ast.walk(f.node):
            if isinstance(n, ast.Assign):
                for t in n.targets:
                    if isinstance(t, ast.Name):
                        assigns.append((t.id, n.value))
                    elif isinstance(t, ast.Tuple):
                        vals = (n.value.elts if isinstance(n.value, ast.Tuple)
                                else self.allocator(n.value) or [None] * len(t.elts))
                        for el, v in zip(t.elts, vals):
                            if isinstance(el, ast.Name):
                                assigns.append((el.id, v))
            elif isinstance(n, ast.AugAssign) and isinstance(n.target, ast.Name):
                assigns.append((n.target.id, n))
            elif isinstance(n, ast.For):
                if not isinstance(n.target, ast.Name):
                    raise TranslationError(f"{f.name} (line {n.lineno}): a for loop needs one loop variable")
                loops.add(n.target.id)
                if isinstance(n.iter, ast.Tuple):  # a loop over numbers takes their type (2.5: double)
                    assigns += [(n.target.id, el) for el in n.iter.elts]
        types: dict[str, object] = {name: INT for name in loops}
        for name, _ in assigns:
            if name not in f.params:
                types.setdefault(name, INT)
        changed = True
        while changed:
            changed = False
            for name, v in assigns:
                if name in f.params:
                    continue
                if v is None:  # an element of a tuple-returning call
                    t = DBL
                elif (alloc := self.allocation(v, f, name)) is not None:
                    t = ("array", alloc[0])
                elif isinstance(v, ast.AugAssign):
                    t = DBL if isinstance(v.op, ast.Div) else self._etype(v.value, f, types, loose=True)
                elif (isinstance(v, ast.Call) and isinstance(v.func, ast.Name) and v.func.id in self.funcs
                      and isinstance(self.funcs[v.func.id].ret, int)):
                    t = ("tuple", self.funcs[v.func.id].ret)
                else:
                    t = self._etype(v, f, types, loose=True)
                old = types[name]
                new = old
                if isinstance(t, tuple) and t[0] == "array":
                    if isinstance(old, tuple) and old != t:
                        raise TranslationError(f"{f.name}: the local array {name!r} is allocated twice")
                    new = t
                elif isinstance(t, tuple):  # a local holding tuples of different lengths: the longest
                    new = t if not isinstance(old, tuple) or t[1] > old[1] else old
                elif t == DBL and old == INT:
                    new = DBL
                if new != old:
                    types[name], changed = new, True
        f.locals = types

    #: the allocations a function may make: a local array of a constant length, or of an array's
    _ALLOC = {"np.zeros": "zeros", "np.empty": "empty", "np.zeros_like": "zeros", "np.empty_like": "empty"}

    def allocation(self, v, f: _Func, target: str):
        """(C length, how it starts: "zeros", "empty" or the C name of the array it copies) when ``v`` allocates
        a one-dimensional array (``np.zeros(n)``, ``np.empty(n)`` of a constant n; ``np.zeros_like(a)``,
        ``np.empty_like(a)``, ``a.copy()`` of an array), else None.  The array is a C99 array of the function
        (a variable-length one for an array's length), so its length must be known where the function starts."""
        if not self._allocates(v):
            return None
        fn = ast.unparse(v.func)
        if isinstance(v.func, ast.Attribute) and v.func.attr == "copy":
            src = v.func.value.id
            if src not in f.arrays:
                raise TranslationError(f"{f.name} (line {v.lineno}): {target} = {src}.copy() of something that "
                                       "is not an array argument")
            return f"{_cname(src)}_n", _cname(src)
        a = v.args[0]
        if fn.endswith("_like"):
            if isinstance(a, ast.Name) and a.id in f.arrays:
                return f"{_cname(a.id)}_n", self._ALLOC[fn]
            own = self._local_array(f, a.id) if isinstance(a, ast.Name) and a.id != target else None
            if own is None:
                raise TranslationError(f"{f.name} (line {v.lineno}): {fn} of something that is not an array")
            return own[0], self._ALLOC[fn]
        if isinstance(a, ast.Constant) and isinstance(a.value, int) and not isinstance(a.value, bool):
            return str(a.value), self._ALLOC[fn]
        if isinstance(a, ast.Name) and isinstance(self.consts.get(a.id), numbers.Integral) and not isinstance(
                self.consts.get(a.id), bool):
            return str(int(self.consts[a.id])), self._ALLOC[fn]
        raise TranslationError(f"{f.name} (line {v.lineno}): {fn} of a length that is not a constant")

    def _allocates(self, v) -> bool:
        """Whether the expression ``v`` has an allocation's form: ``np.zeros(x)``, ``np.empty(x)``,
        ``np.zeros_like(x)``, ``np.empty_like(x)`` (one argument) or ``name.copy()``."""
        if not isinstance(v, ast.Call) or v.keywords:
            return False
        if isinstance(v.func, ast.Attribute) and v.func.attr == "copy":
            return not v.args and isinstance(v.func.value, ast.Name)
        return ast.unparse(v.func) in self._ALLOC and len(v.args) == 1

    def _local_array(self, f: _Func, name: str):
        """The allocation (:meth:`allocation`) of the local array ``name`` of ``f`` (None: not one)."""
        for n in ast.walk(f.node):
            if isinstance(n, ast.Assign) and any(isinstance(t, ast.Name) and t.id == name for t in n.targets):
                return self.allocation(n.value, f, name)
        return None

    # -- expression types ---------------------------------------------------------------------------
    def _etype(self, n, f: _Func, types: dict, loose: bool = False):
        """INT or DBL of a scalar expression."""
        def t(x):
            return self._etype(x, f, types, loose)
        if isinstance(n, ast.Constant):
            if isinstance(n.value, bool) or isinstance(n.value, int):
                return INT
            return DBL
        if isinstance(n, ast.Name):
            if n.id in f.params:
                return ARR if n.id in f.arrays else DBL
            if n.id in types:
                v = types[n.id]
                return v if v in (INT, DBL) else ARR
            if n.id in self.consts:
                return INT if isinstance(self.consts[n.id], (bool, numbers.Integral)) else DBL
            return DBL if loose else INT
        if isinstance(n, ast.Attribute):
            key = ast.unparse(n)
            return DBL if key in self.consts else INT
        if isinstance(n, ast.BinOp):
            if isinstance(n.op, (ast.Div, ast.Pow)):
                return DBL
            return INT if t(n.left) == INT and t(n.right) == INT else DBL
        if isinstance(n, ast.UnaryOp):
            return INT if isinstance(n.op, ast.Not) else t(n.operand)
        if isinstance(n, (ast.Compare, ast.BoolOp)):
            return INT
        if isinstance(n, ast.IfExp):
            return INT if t(n.body) == INT and t(n.orelse) == INT else DBL
        if isinstance(n, ast.Subscript):
            if isinstance(n.value, ast.Attribute) and n.value.attr == "shape":
                return INT
            return DBL
        if isinstance(n, ast.Call):
            fn = ast.unparse(n.func)
            if fn in ("int", "len", "np.int64"):
                return INT
            if fn in ("min", "max", "abs"):
                return INT if all(t(a) == INT for a in n.args) else DBL
            if fn == "math.isfinite" or fn == "math.isnan" or fn == "math.isinf" or fn == "bool":
                return INT
            if fn in self.funcs:
                r = self.funcs[fn].ret
                return r if r in (INT, DBL) else DBL
            return DBL
        return DBL

    # -- translation ---------------------------------------------------------------------------------
    def translate(self, roots, *, static: bool = True, exported=()) -> str:
        """C99 of the functions ``roots`` and every function they call (prototypes first).

        Parameters
        ----------
        roots : sequence of str
            Names of the Python functions wanted.
        static : bool
            Declare every function ``static`` (one translation unit per export).
        exported : sequence of str
            Functions declared without ``static`` even so (a shared library's entry points).

        Returns
        -------
        str
            The C text (without :data:`PRELUDE`).
        """
        names = self.analyse(roots)
        protos, bodies = [], []
        for name in names:
            head = self._signature(self.funcs[name], static and name not in exported)
            protos.append(head + ";")
            bodies.append(_FuncWriter(self, self.funcs[name]).write(head))
        return "\n".join(protos) + "\n\n" + "\n".join(bodies)

    def c_name(self, name: str) -> str:
        """The C name of the Python function ``name``."""
        return self.prefix + name.lstrip("_") if name.startswith("_") else self.prefix + name

    def _signature(self, f: _Func, static: bool) -> str:
        args = []
        for p in f.params:
            if p in f.arrays2d:
                args += [f"double *{_cname(p)}", f"long {_cname(p)}_n", f"long {_cname(p)}_m"]
            elif p in f.arrays:
                args += [f"double *{_cname(p)}", f"long {_cname(p)}_n"]
            else:
                args.append(f"double {_cname(p)}")
        if isinstance(f.ret, int):
            args += [f"double *ret{k}" for k in range(f.ret)]
            rtype = "void"
        else:
            rtype = {None: "void", INT: "long", DBL: "double"}[f.ret]
        return f"{'static ' if static else ''}{rtype} {self.c_name(f.name)}({', '.join(args) or 'void'})"

    def signature(self, name: str) -> dict:
        """What the C function of ``name`` takes and returns (after :meth:`translate`).

        Returns
        -------
        dict
            ``c_name``, ``params`` (Python names), ``arrays`` (those passed as ``double *, long``; a
            two-dimensional one, of ``arrays2d``, as ``double *, long rows, long columns``, row-major),
            ``optional`` (the arrays that may be left out: ``NULL, 0``) and ``returns`` (None, "long", "double"
            or the number of output pointers).
        """
        f = self.funcs[name]
        return {"c_name": self.c_name(name), "params": list(f.params), "arrays": sorted(f.arrays),
                "arrays2d": sorted(f.arrays2d), "optional": sorted(f.optional), "returns": f.ret}


class _Renamed(ast.NodeTransformer):
    """An expression with names replaced (an allocating helper's arguments by a call's)."""

    def __init__(self, names: dict):
        self.names = names

    def visit_Name(self, node):
        return ast.copy_location(ast.Name(self.names.get(node.id, node.id), node.ctx), node)


def _cname(name: str) -> str:
    if name.startswith("_"):
        name = "u" + name
    return name + "_" if name in _RESERVED else name


class _FuncWriter:
    """Writes one function's body."""

    def __init__(self, tr: CTranslator, f: _Func):
        self.tr, self.f = tr, f
        self.lines: list[str] = []
        self.tmp = 0
        self.extra_decls: list[str] = []

    def err(self, node, what: str):
        return TranslationError(f"{self.f.name} (line {getattr(node, 'lineno', '?')}): {what} does not translate "
                                f"to C: {ast.unparse(node)[:80]!r}")

    def new_tmp(self, ctype: str = "double", n: int | None = None) -> str:
        self.tmp += 1
        name = f"t_{self.tmp}"
        self.extra_decls.append(f"{ctype} {name}[{n}];" if n else f"{ctype} {name};")
        return name

    def write(self, head: str) -> str:
        body_lines: list[str] = []
        self.lines = body_lines
        body = self.f.node.body
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) and isinstance(
                body[0].value.value, str):
            doc = " ".join(body[0].value.value.split())
            body = body[1:]
        else:
            doc = ""
        self.block(body, 1)
        decls = []
        for name, t in self.f.locals.items():
            if isinstance(t, tuple) and t[0] == "array":
                decls.append(f"long {_cname(name)}_n = {t[1]};")
                decls.append(f"double {_cname(name)}[{t[1]}];")
            elif isinstance(t, tuple):
                decls.append(f"double {_cname(name)}[{t[1]}];")
            else:
                decls.append(f"{t} {_cname(name)} = 0;")
        out = [head, "{"]
        if doc:
            out.append("    /* " + doc.replace("*/", "* /") + " */")
        out += ["    " + d for d in decls + self.extra_decls]
        out += body_lines
        out.append("}")
        return "\n".join(out) + "\n"

    # -- statements ------------------------------------------------------------------------------
    def emit(self, text: str, depth: int) -> None:
        self.lines.append("    " * depth + text)

    def block(self, stmts, depth: int) -> None:
        for s in stmts:
            self.stmt(s, depth)

    def stmt(self, s, d: int) -> None:
        if isinstance(s, ast.Expr):
            if isinstance(s.value, ast.Constant) and isinstance(s.value.value, str):
                return
            if isinstance(s.value, ast.Call):
                self.emit(self.call(s.value, d) + ";", d)
                return
            raise self.err(s, "an expression statement")
        if isinstance(s, ast.Pass):
            return
        if isinstance(s, ast.Break):
            self.emit("break;", d)
            return
        if isinstance(s, ast.Continue):
            self.emit("continue;", d)
            return
        if isinstance(s, ast.Return):
            self.ret(s, d)
            return
        if isinstance(s, ast.If):
            self.emit(f"if ({self.cond(s.test, d)}) {{", d)
            self.block(s.body, d + 1)
            orelse = s.orelse
            while len(orelse) == 1 and isinstance(orelse[0], ast.If):
                self.emit(f"}} else if ({self.cond(orelse[0].test, d)}) {{", d)
                self.block(orelse[0].body, d + 1)
                orelse = orelse[0].orelse
            if orelse:
                self.emit("} else {", d)
                self.block(orelse, d + 1)
            self.emit("}", d)
            return
        if isinstance(s, ast.While):
            if s.orelse:
                raise self.err(s, "while ... else")
            self.emit(f"while ({self.cond(s.test, d)}) {{", d)
            self.block(s.body, d + 1)
            self.emit("}", d)
            return
        if isinstance(s, ast.For):
            self.for_(s, d)
            return
        if isinstance(s, ast.Assign):
            self.assign(s, d)
            return
        if isinstance(s, ast.AugAssign):
            target = self.lvalue(s.target, d)
            tt = self.type_of(s.target)
            value = self.expr(s.value, d)
            vt = self.type_of(s.value)
            if isinstance(s.op, ast.Div):
                self.emit(f"{target} = (double)({target}) / (double)({value});", d)
            elif isinstance(s.op, ast.Mod):
                fn = "ehas_imod" if tt == INT and vt == INT else "ehas_mod"
                self.emit(f"{target} = {fn}({target}, {value});", d)
            elif isinstance(s.op, ast.FloorDiv):
                fn = "ehas_ifloordiv" if tt == INT and vt == INT else "ehas_floordiv"
                self.emit(f"{target} = {fn}({target}, {value});", d)
            elif isinstance(s.op, ast.Pow):
                self.emit(f"{target} = pow({target}, {value});", d)
            elif isinstance(s.op, (ast.Add, ast.Sub, ast.Mult)):
                op = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*"}[type(s.op)]
                self.emit(f"{target} {op}= {value};", d)
            else:
                raise self.err(s, "this augmented assignment")
            return
        raise self.err(s, f"a {type(s).__name__} statement")

    def for_(self, s: ast.For, d: int) -> None:
        if s.orelse:
            raise self.err(s, "for ... else")
        var = _cname(s.target.id)
        it = s.iter
        if isinstance(it, ast.Call) and isinstance(it.func, ast.Name) and it.func.id in ("range", "prange"):
            a = [self.expr(x, d) for x in it.args]
            if len(a) == 1:
                start, stop, step = "0", a[0], "1"
            elif len(a) == 2:
                start, stop, step = a[0], a[1], "1"
            elif len(a) == 3:
                start, stop, step = a
            else:
                raise self.err(s, "range with these arguments")
            end = self.new_tmp("long")
            if step == "1":
                self.emit(f"{end} = (long)({stop});", d)
                self.emit(f"for ({var} = {start}; {var} < {end}; {var}++) {{", d)
            else:
                stp = self.new_tmp("long")
                self.emit(f"{end} = (long)({stop}); {stp} = (long)({step});", d)
                self.emit(f"for ({var} = {start}; {stp} > 0 ? {var} < {end} : {var} > {end}; {var} += {stp}) {{", d)
            self.block(s.body, d + 1)
            self.emit("}", d)
            return
        if isinstance(it, ast.Tuple):
            vals = [self.expr(x, d) for x in it.elts]
            ctype = self.f.locals.get(s.target.id, INT)
            arr = self.new_tmp(ctype, len(vals))
            k = self.new_tmp("long")
            for j, v in enumerate(vals):
                self.emit(f"{arr}[{j}] = {v};", d)
            self.emit(f"for ({k} = 0; {k} < {len(vals)}; {k}++) {{", d)
            self.emit(f"{var} = {arr}[{k}];", d + 1)
            self.block(s.body, d + 1)
            self.emit("}", d)
            return
        raise self.err(s, "a loop over anything but range(...) or a tuple of numbers")

    def tuple_call(self, v) -> int | None:
        """The number of values the call ``v`` returns when it is a tuple-returning function of the text."""
        if isinstance(v, ast.Call) and isinstance(v.func, ast.Name) and v.func.id in self.tr.funcs:
            r = self.tr.funcs[v.func.id].ret
            if isinstance(r, int):
                return r
        return None

    def allocate(self, target: ast.Name, v, d: int) -> bool:
        """Emits an allocation (:meth:`CTranslator.allocation`) stored in ``target``: a local array filled as
        asked, or an array argument given a copy of its own (``P = P.copy()``: a buffer of the function, the
        argument pointing at it from then on).  False when ``v`` allocates nothing."""
        got = self.tr.allocation(v, self.f, target.id)
        if got is None:
            return False
        length, how = got
        name = _cname(target.id)
        if target.id in self.f.params:
            if target.id not in self.f.arrays or how in ("zeros", "empty") or how != name:
                raise self.err(v, "an array argument given anything but a copy of itself")
            buf = f"{name}__copy"
            self.extra_decls.append(f"double {buf}[{length}];")
            k = self.new_tmp("long")
            self.emit(f"for ({k} = 0; {k} < {length}; {k}++) {buf}[{k}] = {name}[{k}];", d)
            self.emit(f"{name} = {buf};", d)
            return True
        if how == "zeros":
            k = self.new_tmp("long")
            self.emit(f"for ({k} = 0; {k} < {name}_n; {k}++) {name}[{k}] = 0.0;", d)
        elif how != "empty":
            k = self.new_tmp("long")
            self.emit(f"for ({k} = 0; {k} < {name}_n; {k}++) {name}[{k}] = {how}[{k}];", d)
        return True

    def assign(self, s: ast.Assign, d: int) -> None:
        for target in s.targets:
            v = s.value
            if isinstance(target, ast.Name) and self.allocate(target, v, d):
                continue
            if isinstance(target, ast.Tuple):
                n = len(target.elts)
                allocs = self.tr.allocator(v) or (v.elts if isinstance(v, ast.Tuple) else [])
                if len(allocs) == n and all(isinstance(el, ast.Name) for el in target.elts) and all(
                        self.tr.allocation(a, self.f, el.id) is not None for a, el in zip(allocs, target.elts)):
                    for el, a in zip(target.elts, allocs):
                        self.allocate(el, a, d)
                    continue
                if isinstance(v, ast.Tuple):
                    if len(v.elts) != n:
                        raise self.err(s, "unpacking of a different number of values")
                    tmps = []
                    for el, val in zip(target.elts, v.elts):
                        tt = self.new_tmp("double" if self.type_of(val) == DBL else "long")
                        self.emit(f"{tt} = {self.expr(val, d)};", d)
                        tmps.append(tt)
                    for el, tt in zip(target.elts, tmps):
                        if not (isinstance(el, ast.Name) and el.id == "_"):
                            self.emit(f"{self.lvalue(el, d)} = {tt};", d)
                    continue
                k = self.tuple_call(v)
                if k is None or k != n:
                    raise self.err(s, "unpacking of anything but a tuple or a call returning as many values")
                arr = self.new_tmp("double", n)
                self.emit(self.call(v, d, outs=[f"&{arr}[{j}]" for j in range(n)]) + ";", d)
                for j, el in enumerate(target.elts):
                    if not (isinstance(el, ast.Name) and el.id == "_"):
                        self.emit(f"{self.lvalue(el, d)} = {arr}[{j}];", d)
                continue
            if isinstance(target, ast.Subscript) and isinstance(target.slice, ast.Slice):
                sl = target.slice
                if sl.lower or sl.upper or sl.step or not isinstance(target.value, ast.Name):
                    raise self.err(s, "a slice other than x[:]")
                arr = _cname(target.value.id)
                k = self.new_tmp("long")
                val = self.expr(v, d)
                self.emit(f"for ({k} = 0; {k} < {arr}_n; {k}++) {arr}[{k}] = {val};", d)
                continue
            k = self.tuple_call(v)
            if k is not None:
                if not isinstance(target, ast.Name):
                    raise self.err(s, "a tuple stored anywhere but in a local name")
                arr = _cname(target.id)
                self.emit(self.call(v, d, outs=[f"&{arr}[{j}]" for j in range(k)]) + ";", d)
                continue
            self.emit(f"{self.lvalue(target, d)} = {self.expr(v, d)};", d)

    def ret(self, s: ast.Return, d: int) -> None:
        r = self.f.ret
        if s.value is None:
            self.emit("return;", d)
            return
        if isinstance(r, int):
            v = s.value
            if isinstance(v, ast.Tuple):
                tmps = []
                for val in v.elts:
                    tt = self.new_tmp("double")
                    self.emit(f"{tt} = {self.expr(val, d)};", d)
                    tmps.append(tt)
                for j, tt in enumerate(tmps):
                    self.emit(f"*ret{j} = {tt};", d)
                self.emit("return;", d)
                return
            if self.tuple_call(v) == r:
                self.emit(self.call(v, d, outs=[f"ret{j}" for j in range(r)]) + ";", d)
                self.emit("return;", d)
                return
            raise self.err(s, "a return of a tuple function that is not a tuple")
        self.emit(f"return {self.expr(s.value, d)};", d)

    # -- expressions -------------------------------------------------------------------------------
    def type_of(self, n):
        return self.tr._etype(n, self.f, self.f.locals)

    def lvalue(self, n, d: int) -> str:
        if isinstance(n, ast.Name):
            if n.id in self.f.params and n.id not in self.f.arrays:
                return _cname(n.id)
            if n.id not in self.f.locals and n.id not in self.f.params:
                raise self.err(n, "a store to an unknown name")
            return _cname(n.id)
        if isinstance(n, ast.Subscript):
            return self.subscript(n, d)
        raise self.err(n, "this assignment target")

    def cond(self, n, d: int) -> str:
        return self.expr(n, d)

    def index(self, n, arr: str, d: int) -> str:
        if isinstance(n, ast.UnaryOp) and isinstance(n.op, ast.USub) and isinstance(n.operand, ast.Constant):
            return f"{arr}_n - {int(n.operand.value)}"
        if isinstance(n, ast.Constant) and isinstance(n.value, int) and n.value < 0:
            return f"{arr}_n - {-n.value}"
        e = self.expr(n, d)
        return e if self.type_of(n) == INT else f"(long)({e})"

    def subscript(self, n: ast.Subscript, d: int) -> str:
        v = n.value
        if isinstance(n.slice, ast.Tuple) and isinstance(v, ast.Name) and v.id in self.f.arrays2d:
            if len(n.slice.elts) != 2:
                raise self.err(n, "an index of more than two dimensions")
            arr = _cname(v.id)
            i, j = (self.index(x, arr, d) for x in n.slice.elts)
            return f"{arr}[({i}) * {arr}_m + ({j})]"
        if isinstance(n.slice, (ast.Tuple, ast.Slice)):
            raise self.err(n, "a multi-dimensional index or a slice")
        if isinstance(v, ast.Attribute) and v.attr == "shape" and isinstance(v.value, ast.Name):
            if isinstance(n.slice, ast.Constant) and n.slice.value == 1 and v.value.id in self.f.arrays2d:
                return f"{_cname(v.value.id)}_m"
            if not (isinstance(n.slice, ast.Constant) and n.slice.value == 0):
                raise self.err(n, "a shape other than shape[0] (or shape[1] of a two-dimensional array)")
            return f"{_cname(v.value.id)}_n"
        if isinstance(v, ast.Name) and v.id in self.f.arrays2d:
            raise self.err(n, "a row of a two-dimensional array")
        if isinstance(v, ast.Name):
            if v.id in self.f.arrays:
                return f"{_cname(v.id)}[{self.index(n.slice, _cname(v.id), d)}]"
            t = self.f.locals.get(v.id)
            if isinstance(t, tuple):
                return f"{_cname(v.id)}[{self.index(n.slice, _cname(v.id), d)}]"
            raise self.err(n, "an index into something that is not an array")
        k = self.tuple_call(v)
        if k is not None:
            if not isinstance(n.slice, ast.Constant):
                raise self.err(n, "a variable index into a call's tuple")
            arr = self.new_tmp("double", k)
            self.emit(self.call(v, d, outs=[f"&{arr}[{j}]" for j in range(k)]) + ";", d)
            return f"{arr}[{int(n.slice.value)}]"
        raise self.err(n, "this index")

    def expr(self, n, d: int) -> str:
        e = self.expr
        if isinstance(n, ast.Constant):
            if isinstance(n.value, (bool, int, float)):
                return _num(n.value)
            raise self.err(n, "a constant that is not a number")
        if isinstance(n, ast.Name):
            if n.id in self.f.params or n.id in self.f.locals:
                return _cname(n.id)
            if n.id in self.tr.consts:
                return _num(self.tr.consts[n.id])
            if n.id in ("True", "False"):
                return "1" if n.id == "True" else "0"
            raise self.err(n, f"the name {n.id!r} (not an argument, local or known constant)")
        if isinstance(n, ast.Attribute):
            key = ast.unparse(n)
            if key in self.tr.consts:
                return _num(self.tr.consts[key])
            raise self.err(n, "this attribute")
        if isinstance(n, ast.Subscript):
            return self.subscript(n, d)
        if isinstance(n, ast.UnaryOp):
            if isinstance(n.op, ast.USub):
                return f"(-{e(n.operand, d)})"
            if isinstance(n.op, ast.UAdd):
                return f"(+{e(n.operand, d)})"
            if isinstance(n.op, ast.Not):
                return f"(!{e(n.operand, d)})"
            raise self.err(n, "this unary operator")
        if isinstance(n, ast.BinOp):
            a, b = e(n.left, d), e(n.right, d)
            ints = self.type_of(n.left) == INT and self.type_of(n.right) == INT
            op = type(n.op)
            if op is ast.Add:
                return f"({a} + {b})"
            if op is ast.Sub:
                return f"({a} - {b})"
            if op is ast.Mult:
                return f"({a} * {b})"
            if op is ast.Div:
                return f"((double)({a}) / (double)({b}))" if ints else f"({a} / {b})"
            if op is ast.FloorDiv:
                return f"ehas_ifloordiv({a}, {b})" if ints else f"ehas_floordiv({a}, {b})"
            if op is ast.Mod:
                return f"ehas_imod({a}, {b})" if ints else f"ehas_mod({a}, {b})"
            if op is ast.Pow:
                return f"pow({a}, {b})"
            raise self.err(n, "this operator")
        if isinstance(n, ast.BoolOp):
            op = " && " if isinstance(n.op, ast.And) else " || "
            return "(" + op.join(e(v, d) for v in n.values) + ")"
        if isinstance(n, ast.Compare):
            ops = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}
            parts, left = [], n.left
            for op, right in zip(n.ops, n.comparators):
                if (isinstance(op, (ast.Is, ast.IsNot)) and isinstance(right, ast.Constant) and right.value is None
                        and isinstance(left, ast.Name) and left.id in self.f.optional):
                    parts.append(f"({_cname(left.id)} {'==' if isinstance(op, ast.Is) else '!='} NULL)")
                    left = right
                    continue
                if type(op) not in ops:
                    raise self.err(n, "this comparison")
                parts.append(f"({e(left, d)} {ops[type(op)]} {e(right, d)})")
                left = right
            return parts[0] if len(parts) == 1 else "(" + " && ".join(parts) + ")"
        if isinstance(n, ast.IfExp):
            return f"({e(n.test, d)} ? {e(n.body, d)} : {e(n.orelse, d)})"
        if isinstance(n, ast.Call):
            return self.call(n, d)
        raise self.err(n, f"a {type(n).__name__} expression")

    def call(self, n: ast.Call, d: int, outs: list | None = None) -> str:
        if n.keywords:
            raise self.err(n, "a call with keyword arguments")
        fn = ast.unparse(n.func)
        args = n.args
        if fn in self.tr.funcs:
            callee = self.tr.funcs[fn]
            if len(args) != len(callee.params):
                raise self.err(n, f"a call of {fn} with {len(args)} arguments (it takes {len(callee.params)})")
            parts = []
            for p, a in zip(callee.params, args):
                if p in callee.arrays:
                    if not isinstance(a, ast.Name):
                        raise self.err(n, f"passing {ast.unparse(a)!r} as the array {p}")
                    name = _cname(a.id)
                    if (a.id in self.f.arrays2d) != (p in callee.arrays2d):
                        raise self.err(n, f"passing {a.id!r} as the array {p} of another number of dimensions")
                    if a.id in self.f.arrays2d:
                        parts += [name, f"{name}_n", f"{name}_m"]
                    elif a.id in self.f.arrays:
                        parts += [name, f"{name}_n"]
                    elif isinstance(self.f.locals.get(a.id), tuple) and self.f.locals[a.id][0] == "array":
                        parts += [name, f"{name}_n"]
                    elif isinstance(self.f.locals.get(a.id), tuple):
                        parts += [name, str(self.f.locals[a.id][1])]
                    else:
                        raise self.err(n, f"passing {a.id!r}, not an array, as the array {p}")
                else:
                    parts.append(self.expr(a, d))
            k = self.tuple_call(n)
            if k is not None:
                if outs is None:
                    raise self.err(n, "a tuple-returning call used as a number")
                parts += outs
            return f"{self.tr.c_name(fn)}({', '.join(parts)})"
        a = [self.expr(x, d) for x in args]
        types = [self.type_of(x) for x in args]
        if fn.startswith("math."):
            m = fn[5:]
            if m == "degrees":
                return f"({a[0]} * {_num(180 / math.pi)})"
            if m == "radians":
                return f"({a[0]} * {_num(math.pi / 180)})"
            if m in ("isfinite", "isnan", "isinf"):
                return f"(long){m}({a[0]})"
            if m in _MATH:
                return f"{_MATH[m]}({', '.join(a)})"
            raise self.err(n, f"math.{m}")
        if fn in ("min", "max"):
            if len(a) < 2:
                raise self.err(n, f"{fn} of one argument (an iterable)")
            ints = all(t == INT for t in types)
            h = ("ehas_i" if ints else "ehas_") + fn
            out = a[0]
            for x in a[1:]:
                out = f"{h}({out}, {x})"
            return out
        if fn in ("np.max", "np.min") and len(args) == 1 and isinstance(args[0], ast.Name) and (
                args[0].id in self.f.arrays and args[0].id not in self.f.arrays2d):
            arr, t, k = _cname(args[0].id), self.new_tmp("double"), self.new_tmp("long")
            self.emit(f"{t} = {arr}[0];", d)
            self.emit(f"for ({k} = 1; {k} < {arr}_n; {k}++) if ({arr}[{k}] {'>' if fn == 'np.max' else '<'} {t}) "
                      f"{t} = {arr}[{k}];", d)
            return t
        if fn == "abs":
            return f"labs({a[0]})" if types[0] == INT else f"fabs({a[0]})"
        if fn in ("int", "np.int64"):
            return f"(long)({a[0]})"
        if fn in ("float", "np.float64"):
            return f"(double)({a[0]})"
        if fn == "len":
            if isinstance(args[0], ast.Name) and args[0].id in self.f.arrays:
                return f"{_cname(args[0].id)}_n"
            raise self.err(n, "len of something that is not an array argument")
        raise self.err(n, f"a call of {fn}")


def translate(text: str, roots, constants: dict | None = None, prefix: str = "ehas_") -> str:
    """C99 of the functions ``roots`` of the Python ``text`` and of what they call, after :data:`PRELUDE`.

    Parameters
    ----------
    text : str
        Python module text in the subset of the module docstring.
    roots : sequence of str
        The functions wanted.
    constants : dict, optional
        Constant names the functions read, by value.
    prefix : str
        Prefix of the C functions' names.

    Returns
    -------
    str
        A C99 translation unit (static functions).
    """
    return PRELUDE + "\n" + CTranslator(text, constants, prefix).translate(roots)


def function_source(fn, name: str) -> str:
    """The text of the plain function ``fn`` (a law, an effect's term) as a top-level ``def name(...)``: the
    very text :mod:`ehas_env.physics.codegen` copies into the model (decorators dropped).

    Parameters
    ----------
    fn : function
        The Python function (a static method's function is fine).
    name : str
        Its name in the text.

    Returns
    -------
    str
        Python text.
    """
    from ehas_env.physics.model_source import _term_source

    holder = type("law", (), {"name": name, "law": staticmethod(getattr(fn, "__func__", fn))})
    return _term_source(holder, "law", name).replace('@njit(cache=True, inline="always")\n', "")


def methods_source(cls, names) -> tuple[str, dict]:
    """Methods of ``cls`` as plain functions: ``self`` dropped, each ``self.attr`` read an argument
    ``self_attr`` appended to the method's own (sorted), ``self.m(...)`` a call of ``m`` with them.

    Parameters
    ----------
    cls : type
        The class (e.g. a learning controller's cycle table).
    names : sequence of str
        The methods wanted (those they call through ``self`` must be among them).

    Returns
    -------
    tuple of (str, dict)
        The Python text, and per function the ``self`` attributes appended to its arguments, in order.
    """
    import inspect
    import textwrap

    trees = {}
    for n in names:
        src = textwrap.dedent(inspect.getsource(getattr(cls, n)))
        fn = ast.parse(src).body[0]
        fn.decorator_list = []
        if not fn.args.args or fn.args.args[0].arg != "self":
            raise TranslationError(f"{cls.__name__}.{n}: not a method taking self")
        fn.args.args = fn.args.args[1:]
        trees[n] = fn
    own = {n: {a.attr for a in ast.walk(t) if isinstance(a, ast.Attribute) and isinstance(a.value, ast.Name)
               and a.value.id == "self" and a.attr not in trees} for n, t in trees.items()}
    calls = {n: {a.func.attr for a in ast.walk(t) if isinstance(a, ast.Call) and isinstance(a.func, ast.Attribute)
                 and isinstance(a.func.value, ast.Name) and a.func.value.id == "self" and a.func.attr in trees}
             for n, t in trees.items()}
    changed = True
    while changed:  # a method's attributes include those of the methods it calls
        changed = False
        for n in trees:
            for m in calls[n]:
                if not own[m] <= own[n]:
                    own[n] |= own[m]
                    changed = True
    attrs = {n: sorted(own[n]) for n in trees}

    class _Rewrite(ast.NodeTransformer):
        def visit_Call(self, node):
            f = node.func
            if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "self" \
                    and f.attr in trees:
                node.func = ast.Name(f.attr, ast.Load())
                node.args += [ast.Name(f"self_{a}", ast.Load()) for a in attrs[f.attr]]
            self.generic_visit(node)
            return node

        def visit_Attribute(self, node):
            self.generic_visit(node)
            if isinstance(node.value, ast.Name) and node.value.id == "self":
                return ast.copy_location(ast.Name(f"self_{node.attr}", ast.Load()), node)
            return node

    out = []
    for n, fn in trees.items():
        fn = _Rewrite().visit(fn)
        fn.args.args += [ast.arg(f"self_{a}") for a in attrs[n]]
        out.append(ast.unparse(ast.fix_missing_locations(fn)))
    return "\n\n".join(out) + "\n", attrs


def layout_constants() -> dict:
    """The numeric names of :mod:`ehas_env.physics.layout` (what a generated model's ``import *`` gives it).

    Returns
    -------
    dict of str to number
        ``I_*``, ``S_*``, ``O_*``, ``N_*``, ``WHITE_BOX``, ... by name.
    """
    from ehas_env.physics import layout

    return {k: v for k, v in vars(layout).items() if not k.startswith("_") and isinstance(v, (int, float))
            and not isinstance(v, bool)}


def model_c(spec, roots=("measure", "advance", "reference_point", "sense", "quantize", "control_law",
                         "valve_current", "project"), prefix: str = "ehm_", exported=()) -> tuple[str, CTranslator]:
    """The C of a generated model: ``spec.source()`` (:class:`ehas_env.physics.model_source.ModelSource`, the
    text numba compiles) translated from ``roots``.

    Parameters
    ----------
    spec : ModelSource
        The model's effects and laws.
    roots : sequence of str
        The model's functions wanted (default: what a fixed-step driver calls: ``measure``, ``advance``,
        ``reference_point``, ``sense``, ``quantize``, ``control_law``, ``valve_current``, ``project``).
    prefix : str
        Prefix of the C functions' names.
    exported : sequence of str
        Functions left visible outside the unit (:meth:`CTranslator.translate`); every other one is ``static``.

    Returns
    -------
    tuple of (str, CTranslator)
        The C translation unit (with :data:`PRELUDE`) and the translator (its :meth:`CTranslator.signature`).
    """
    tr = CTranslator(spec.source(), layout_constants(), prefix)
    return PRELUDE + "\n" + tr.translate(list(roots), exported=exported), tr
