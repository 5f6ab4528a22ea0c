"""The vector width of the net kernels' loops, read from the assembly numba generates for them.

A loop is vectorised when its body does its floating-point arithmetic with packed instructions
(vaddpd, vmulpd, vsqrtpd, ...); their register says the width: xmm 2, ymm 4, zmm 8 float64
lanes, twice as many float32 ones (vaddps, ...: reported as "ymm/f32" and so on). numba shows no assembly for a kernel it loaded from its cache, so each kernel is compiled
afresh here (an uncached copy of the same Python function, the same options, for the same
argument types) and its innermost loops, found as the code between a label and a backward jump
to it, are sorted by what their arithmetic uses. A vectorised loop comes with scalar copies
(the remainder of a row that is not a multiple of the width, and the fallback LLVM takes when
its runtime alias checks fail), so a kernel is reported by its widest loop and by the loops
that have only scalar arithmetic.
"""
import re
from collections import Counter

import numba

# Floating-point arithmetic of x86-64 (SSE, AVX, AVX-512), packed (pd/ps) or scalar (sd/ss).
_ARITH = re.compile(r"^v?(?:add|sub|mul|div|sqrt|max|min|rsqrt14|rcp14|fn?m(?:add|sub)\d{3})(p|s)([ds])$")
_LABEL = re.compile(r"^(\.L\w+):")
_JUMP = re.compile(r"^\s+j\w+\s+(\.L\w+)")
LANES = {"zmm": 8, "ymm": 4, "xmm": 2, "zmm/f32": 16, "ymm/f32": 8, "xmm/f32": 4, "scalar": 1}  # lanes per register


def _width(line: str, packed: bool, single: bool) -> str:
    if not packed:
        return "scalar"
    register = next((r for r in ("zmm", "ymm") if f"%{r}" in line), "xmm")
    return register + "/f32" if single else register


def innermost_loops(asm: str) -> list[Counter]:
    """Per innermost loop of an assembly listing: its arithmetic instructions counted by width."""
    lines = asm.splitlines()
    labels: dict[str, int] = {}
    loops = []
    for n, line in enumerate(lines):
        label = _LABEL.match(line)
        if label:
            labels[label.group(1)] = n
        jump = _JUMP.match(line)
        if jump and labels.get(jump.group(1), n) < n:
            loops.append((labels[jump.group(1)], n))
    inner = [a for a in loops if not any(b != a and a[0] <= b[0] and b[1] <= a[1] for b in loops)]
    out = []
    for start, end in inner:
        widths = Counter()
        for line in lines[start:end + 1]:
            parts = line.split()
            op = _ARITH.match(parts[0]) if parts else None
            if op:
                widths[_width(line, op.group(1) == "p", op.group(2) == "s")] += 1
        if widths:
            out.append(widths)
    return out


def vector_report(kernel, args) -> dict:
    """How the loops of `kernel` (a numba dispatcher) compile for `args`' types.

    Returns:
        {"width": widest register of a loop's arithmetic ("zmm", "ymm", "xmm" or "scalar"),
        "lanes": float64 lanes of that width, "packed_ops": arithmetic instructions in the
        widest loop, "loops": innermost loops with arithmetic, "scalar_loops": those with only
        scalar arithmetic (remainders and alias fallbacks of vector loops, or loops that did
        not vectorise)}.
    """
    options = {k: v for k, v in kernel.targetoptions.items() if k not in ("cache", "nopython")}
    fresh = numba.njit(**options)(kernel.py_func)
    signature = tuple(numba.typeof(a) for a in args)
    fresh.compile(signature)
    loops = innermost_loops(fresh.inspect_asm(signature))
    best = max(loops, key=lambda w: (max(LANES[k] for k in w), sum(w.values())), default=Counter())
    width = max(best, key=lambda k: LANES[k], default="scalar")
    return {
        "width": width,
        "lanes": LANES[width],
        "packed_ops": sum(n for k, n in best.items() if k != "scalar"),
        "loops": len(loops),
        "scalar_loops": sum(1 for w in loops if set(w) == {"scalar"}),
    }
