//! The machine code lavapipe compiled, as `GALLIVM_DEBUG=asm` prints it, and the counts
//! `trilab driver-stats` derives from it (the way shader-db counts a real compiler's output).
//!
//! The text is gallivm's own dump (`lp_disassemble` in Mesa's `gallivm/lp_bld_debug.cpp`): for
//! each JIT-compiled function its LLVM name on a line of its own (`cs_co_variant:`), then one
//! line per instruction, `<hex offset>:\t<mnemonic>\t<operands>`, in LLVM MC's AT&T syntax
//! (source operands first, destination last), disassembled from the bytes in memory. Being a
//! disassembly of bytes, it carries none of the `# 32-byte Spill` / `# 32-byte Reload` comments
//! LLVM's assembly printer writes, so spills and reloads are recognised by their shape (below).
//! The dump stops at a `ret` that no earlier jump passes, and after 96 KiB with `disassembly
//! larger than ... bytes, aborting` (then [`FunctionDump::truncated`] is set).
//!
//! What is counted, per function and summed over a kernel's functions ([`AsmStats`]):
//! - **instructions**: every disassembled instruction;
//! - **vector spills**: full-register moves (`movaps`, `vmovups`, `vmovdqa64`, ...) from an
//!   `xmm`/`ymm`/`zmm` register to a stack slot, `off(%rsp)` or `off(%rbp)` with no index
//!   register, that the function reads back at that fixed offset somewhere (a spill is always
//!   reloaded, or LLVM would not have written it); **stack stores**: such moves to slots never
//!   read at a fixed offset. These are the shader's local arrays (the traversal stack, one
//!   32-bit entry per lane, read and written with an index register, `3616(%rsp,%rcx,4)`),
//!   which llvmpipe zero-fills with one vector store per entry: in `raycast.mt.closest` at 256
//!   bits 128 of the 273 vector stores to fixed slots are that, 145 are spills;
//!   **vector reloads**: full-register moves from a stack slot into a vector register;
//!   **folded reloads**: any other vector instruction that reads a stack slot (`vaddps
//!   64(%rsp), %ymm1, %ymm2`, `vcmpgeps 192(%rsp), %ymm2, %k2`; LLVM's `Folded Reload`);
//! - **mask spills / reloads**: the same for AVX-512 mask registers (`kmovw %k1, 12(%rsp)`);
//! - **calls**, split by how the target is reached: **table calls** through a pointer loaded
//!   from memory (`callq *40(%rax)`, `callq *(%rax)`): llvmpipe's per-descriptor function
//!   tables, the texel-fetch, image and size helpers it JIT-compiles for each texel buffer or
//!   image view and calls from the shader; **host calls** through a register loaded with an
//!   absolute address (`movabsq $..., %rax; callq *%rax`: C functions of the driver, such as
//!   the coroutine's memory hooks); **direct calls** (`callq 0x...`);
//! - **stack bytes**: the frame the function reserves (`subq $N, %rsp`, the largest);
//! - how the shader loads memory other than its stack (issue 53: are a packet's node loads
//!   scalar?): **gathers**, the hardware's per-lane loads (`vpgatherdd`, `vgatherdps`, ...);
//!   **lane loads**, a lane's value loaded into one element of a vector (`vpinsrd $3, (%rax),
//!   %xmm0`, `vinsertps`, `vpinsrq`, or a broadcast load whose register a blend within the next
//!   [`BLEND_WINDOW`] instructions takes one lane of: `vpbroadcastd (%rax,%rsi,4), %ymm2` ...
//!   `vpblendd $16, %ymm2, %ymm5, %ymm5`, how gallivm writes a gather out lane by lane into a
//!   256-bit register); **broadcast loads**, the other broadcasts from memory, one value for
//!   every lane (an address the same in every lane: the scalar load a GPU would issue).

use serde::Serialize;

/// One instruction of a dump.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Instruction {
    /// Byte offset from the function's start.
    pub offset: u64,
    pub mnemonic: String,
    /// The operands as printed (AT&T: sources first, destination last); may be empty.
    pub operands: String,
}

/// One function of a dump.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FunctionDump {
    pub name: String,
    pub instructions: Vec<Instruction>,
    /// gallivm gave up (`invalid` bytes, or past its size limit): the counts are a lower bound.
    pub truncated: bool,
}

/// Splits a dump into its functions. Lines that are neither a function name nor an instruction
/// (blank lines, other messages on the same stream) are skipped; an instruction line before
/// any name is an error, as is a name without instructions.
pub fn parse(text: &str) -> Result<Vec<FunctionDump>, String> {
    let mut out: Vec<FunctionDump> = vec![];
    for (i, line) in text.lines().enumerate() {
        if let Some(ins) = instruction(line) {
            let Some(f) = out.last_mut() else {
                return Err(format!("line {}: an instruction before any function name: `{line}`", i + 1));
            };
            f.instructions.push(ins);
        } else if let Some(name) = function_name(line) {
            out.push(FunctionDump { name: name.to_owned(), instructions: vec![], truncated: false });
        } else if line.trim() == "invalid" || line.contains("bytes, aborting") {
            if let Some(f) = out.last_mut() {
                f.truncated = true;
            }
        }
    }
    if let Some(f) = out.iter().find(|f| f.instructions.is_empty()) {
        return Err(format!("function `{}` has no instructions", f.name));
    }
    Ok(out)
}

/// `cs_co_variant:`: a name of LLVM identifier characters at the start of the line, then `:`.
fn function_name(line: &str) -> Option<&str> {
    let name = line.strip_suffix(':')?;
    let ok = !name.is_empty()
        && !name.starts_with(|c: char| c.is_ascii_whitespace() || c.is_ascii_digit())
        && name.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '$'));
    ok.then_some(name)
}

/// `   4d:\tvzeroupper` or `  175f:\tcallq\t*(%rax)`.
fn instruction(line: &str) -> Option<Instruction> {
    if !line.starts_with([' ', '\t']) {
        return None;
    }
    let (offset, rest) = line.trim_start().split_once(':')?;
    let offset = u64::from_str_radix(offset, 16).ok()?;
    let rest = rest.trim();
    if rest.is_empty() {
        return None;
    }
    let (mnemonic, operands) = match rest.split_once(|c: char| c.is_ascii_whitespace()) {
        Some((m, o)) => (m, o.trim()),
        None => (rest, ""),
    };
    Some(Instruction { offset, mnemonic: mnemonic.to_owned(), operands: operands.to_owned() })
}

/// What one function or a whole kernel compiled to.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct AsmStats {
    pub instructions: u64,
    pub vector_spills: u64,
    /// Vector stores to fixed stack slots never read back at a fixed offset (local arrays).
    pub stack_stores: u64,
    pub vector_reloads: u64,
    /// Instructions other than moves that read a vector operand from a stack slot.
    pub folded_reloads: u64,
    pub mask_spills: u64,
    pub mask_reloads: u64,
    /// Every call.
    pub calls: u64,
    /// Calls through a pointer loaded from memory: llvmpipe's per-descriptor helper functions
    /// (texel fetch, image, size).
    pub table_calls: u64,
    /// Calls through a register holding an absolute address: C functions of the driver.
    pub host_calls: u64,
    /// The largest stack frame a function reserves, bytes.
    pub stack_bytes: u64,
    /// Hardware gathers (`vpgatherdd`, `vgatherdps`, ...).
    pub gathers: u64,
    /// Inserts of one element loaded from memory other than the stack (`vpinsrd`, `vinsertps`,
    /// `vpinsrq` with a memory source): a gather written out lane by lane.
    pub lane_loads: u64,
    /// Broadcasts from memory other than the stack (`vpbroadcastd`, `vbroadcastss`, ...): one
    /// load for every lane, from an address the same in all of them.
    pub broadcast_loads: u64,
}

impl std::ops::AddAssign for AsmStats {
    fn add_assign(&mut self, o: AsmStats) {
        self.instructions += o.instructions;
        self.vector_spills += o.vector_spills;
        self.stack_stores += o.stack_stores;
        self.vector_reloads += o.vector_reloads;
        self.folded_reloads += o.folded_reloads;
        self.mask_spills += o.mask_spills;
        self.mask_reloads += o.mask_reloads;
        self.calls += o.calls;
        self.table_calls += o.table_calls;
        self.host_calls += o.host_calls;
        self.stack_bytes = self.stack_bytes.max(o.stack_bytes);
        self.gathers += o.gathers;
        self.lane_loads += o.lane_loads;
        self.broadcast_loads += o.broadcast_loads;
    }
}

/// Splits AT&T operands at the commas outside parentheses: `8(%rsp,%rax,4), %ymm0` gives
/// `8(%rsp,%rax,4)` and `%ymm0`.
fn operands(s: &str) -> Vec<&str> {
    let (mut out, mut depth, mut start) = (vec![], 0i32, 0);
    for (i, c) in s.char_indices() {
        match c {
            '(' => depth += 1,
            ')' => depth -= 1,
            ',' if depth == 0 => {
                out.push(s[start..i].trim());
                start = i + 1;
            }
            _ => {}
        }
    }
    if !s[start..].trim().is_empty() {
        out.push(s[start..].trim());
    }
    out
}

/// A stack slot: `off(%rsp)`, `(%rsp)`, `-off(%rbp)`, with no index register.
fn is_stack_slot(op: &str) -> bool {
    let op = op.strip_prefix('*').unwrap_or(op);
    op.ends_with("(%rsp)") || op.ends_with("(%rbp)")
}

fn is_vector_reg(op: &str) -> bool {
    ["%xmm", "%ymm", "%zmm"].iter().any(|p| op.starts_with(p))
}

/// A mask register, possibly with its `{...}` decorations stripped by the caller.
fn is_mask_reg(op: &str) -> bool {
    op.starts_with("%k") && op[2..].chars().all(|c| c.is_ascii_digit()) && op.len() > 2
}

/// A full-register vector move (no scalar `movss`/`movd`, no broadcast, no extension).
fn is_vector_move(m: &str) -> bool {
    let m = m.strip_prefix('v').unwrap_or(m);
    matches!(m, "movaps" | "movups" | "movapd" | "movupd" | "movdqa" | "movdqu")
        || (m.starts_with("movdqa") || m.starts_with("movdqu")) && m[6..].chars().all(|c| c.is_ascii_digit())
}

fn is_mask_move(m: &str) -> bool {
    matches!(m, "kmovb" | "kmovw" | "kmovd" | "kmovq")
}

/// The operand without AVX-512 decorations (`%ymm0 {%k1}` -> `%ymm0`).
fn bare(op: &str) -> &str {
    op.split_whitespace().next().unwrap_or(op)
}

/// Scalar moves into or out of a vector register (`vmovss`, `vmovd`, ...): not vector reloads.
fn is_scalar_move(m: &str) -> bool {
    let m = m.strip_prefix('v').unwrap_or(m);
    matches!(m, "movss" | "movsd" | "movd" | "movq" | "movlps" | "movhps" | "movlpd" | "movhpd")
}

/// The stack slots the function reads at a fixed offset: every source operand (all but the
/// last) of every instruction that is not an address computation (`lea`).
fn slots_read(f: &FunctionDump) -> std::collections::HashSet<&str> {
    let mut read = std::collections::HashSet::new();
    for ins in f.instructions.iter().filter(|i| !i.mnemonic.starts_with("lea")) {
        let ops = operands(&ins.operands);
        for op in ops.iter().take(ops.len().saturating_sub(1)) {
            let op = bare(op);
            if is_stack_slot(op) {
                read.insert(op);
            }
        }
    }
    read
}

/// A memory operand off the stack (`(%rax)`, `16(%rdx,%rcx,4)`; AT&T memory operands are the
/// ones with parentheses): its base register is not `%rsp` or `%rbp` (the stack's slots and
/// the shader's local arrays, `3616(%rsp,%rcx,4)`, are not).
fn is_memory(op: &str) -> bool {
    let Some((_, inside)) = op.split_once('(') else { return false };
    !op.starts_with('*') && !inside.starts_with("%rsp") && !inside.starts_with("%rbp")
}

/// A load into one element of a vector: `[v]pinsr{b,w,d,q}`, `[v]insertps`.
fn is_lane_insert(m: &str) -> bool {
    let m = m.strip_prefix('v').unwrap_or(m);
    matches!(m, "pinsrb" | "pinsrw" | "pinsrd" | "pinsrq" | "insertps")
}

/// A load of one value into every lane: `vpbroadcast{b,w,d,q}`, `vbroadcastss`, `vbroadcastsd`.
fn is_broadcast(m: &str) -> bool {
    matches!(m, "vpbroadcastb" | "vpbroadcastw" | "vpbroadcastd" | "vpbroadcastq" | "vbroadcastss" | "vbroadcastsd")
}

/// How far after a broadcast load a blend of its register makes it a lane load.
pub const BLEND_WINDOW: usize = 8;

/// A blend of vector elements (`vpblendd`, `vblendps`, AVX-512's `vpblendmd`, ...).
fn is_blend(m: &str) -> bool {
    let m = m.strip_prefix('v').unwrap_or(m);
    m.starts_with("pblend") || m.starts_with("blend")
}

/// The counts of one function.
pub fn stats(f: &FunctionDump) -> AsmStats {
    let mut s = AsmStats { instructions: f.instructions.len() as u64, ..Default::default() };
    let read = slots_read(f);
    let mut prev: Option<&Instruction> = None;
    for (at, ins) in f.instructions.iter().enumerate() {
        let m = ins.mnemonic.as_str();
        let ops = operands(&ins.operands);
        let (first, last) = (ops.first().map(|o| bare(o)), ops.last().map(|o| bare(o)));
        if m.contains("gather") {
            s.gathers += 1;
        } else if is_lane_insert(m) && ops.iter().any(|o| is_memory(bare(o))) {
            s.lane_loads += 1;
        } else if is_broadcast(m) && first.is_some_and(is_memory) {
            let reg = last.unwrap_or("");
            let blended = f.instructions[at + 1..].iter().take(BLEND_WINDOW).any(|n| {
                let ops = operands(&n.operands);
                is_blend(&n.mnemonic) && ops[..ops.len().saturating_sub(1)].iter().any(|o| bare(o) == reg)
            });
            if blended {
                s.lane_loads += 1;
            } else {
                s.broadcast_loads += 1;
            }
        }
        if m.starts_with("call") {
            s.calls += 1;
            let target = ops.first().copied().unwrap_or("");
            if let Some(t) = target.strip_prefix('*') {
                if t.contains('(') {
                    s.table_calls += 1;
                } else if let Some(p) = prev {
                    // `movabsq $address, %reg` right before `callq *%reg`.
                    let p_ops = operands(&p.operands);
                    if p.mnemonic.starts_with("movabs") && p_ops.last() == Some(&t) {
                        s.host_calls += 1;
                    }
                }
            }
        } else if m == "subq" && last == Some("%rsp") {
            if let Some(n) = first.and_then(|f| f.strip_prefix('$')).and_then(|n| n.parse::<u64>().ok()) {
                s.stack_bytes = s.stack_bytes.max(n);
            }
        } else if let (Some(first), Some(last), true) = (first, last, ops.len() >= 2) {
            if is_vector_move(m) {
                if is_vector_reg(first) && is_stack_slot(last) {
                    if read.contains(last) {
                        s.vector_spills += 1;
                    } else {
                        s.stack_stores += 1;
                    }
                } else if is_stack_slot(first) && is_vector_reg(last) {
                    s.vector_reloads += 1;
                }
            } else if is_mask_move(m) {
                if is_mask_reg(first) && is_stack_slot(last) {
                    s.mask_spills += 1;
                } else if is_stack_slot(first) && is_mask_reg(last) {
                    s.mask_reloads += 1;
                }
            } else if !is_scalar_move(m)
                && !m.starts_with("lea")
                && ops[..ops.len() - 1].iter().any(|o| is_stack_slot(bare(o)))
                && ops.iter().any(|o| is_vector_reg(bare(o)) || is_mask_reg(bare(o)))
            {
                s.folded_reloads += 1;
            }
        }
        prev = Some(ins);
    }
    s
}

/// Whether a function is part of a compute shader variant: llvmpipe names them `cs_variant`
/// (the entry point), `cs_co_variant` (the shader as a coroutine) and its `.resume` and
/// `.destroy` parts; the helpers it compiles for descriptors are `sample`, `image`, `size`, ...
pub fn is_compute_shader(name: &str) -> bool {
    name == "cs_variant" || name.starts_with("cs_co_variant")
}

/// A kernel's figures: [`AsmStats`] summed over its compute-shader functions, and the calls
/// from the shader's body into llvmpipe's per-descriptor helpers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct KernelAsm {
    #[serde(flatten)]
    pub total: AsmStats,
    /// Table calls in `cs_co_variant` (the shader's body): the texel-fetch, image and size
    /// helpers llvmpipe JIT-compiles per descriptor and calls through the descriptor's function
    /// table. (The table calls of `cs_variant` are the coroutine's resume and destroy.)
    pub helper_calls: u64,
    /// Whether gallivm cut a function's dump short: the counts are then lower bounds.
    pub truncated: bool,
}

/// The figures of the compute-shader functions among `functions` ([`is_compute_shader`]);
/// `None` if there are none.
pub fn kernel(functions: &[FunctionDump]) -> Option<KernelAsm> {
    let mut k = KernelAsm::default();
    let mut any = false;
    for f in functions.iter().filter(|f| is_compute_shader(&f.name)) {
        any = true;
        let s = stats(f);
        k.total += s;
        if f.name.starts_with("cs_co_variant") {
            k.helper_calls += s.table_calls;
        }
        k.truncated |= f.truncated;
    }
    any.then_some(k)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A whole real dump: `GALLIVM_DEBUG=asm MESA_SHADER_CACHE_DISABLE=true trilab raycast
    /// --scene cornell` (kernel `raycast.mt.closest`) on lavapipe, Mesa 25.0.7, LLVM 15, 256-bit
    /// vectors. The expected figures are those of `tests/data/lavapipe-asm/count.awk`, an
    /// independent count (README.md there), not of this parser.
    const DUMP: &str = include_str!("../../../tests/data/lavapipe-asm/raycast.mt.closest.txt");

    fn function<'a>(fs: &'a [FunctionDump], name: &str) -> &'a FunctionDump {
        fs.iter().find(|f| f.name == name).unwrap()
    }

    #[test]
    fn parses_every_function_of_a_real_dump() {
        let fs = parse(DUMP).unwrap();
        let names: Vec<&str> = fs.iter().map(|f| f.name.as_str()).collect();
        let mut expected = vec!["sample"; 6];
        expected.extend(["size", "size", "image", "image", "image", "image"]);
        expected.extend(["cs_variant", "cs_co_variant", "cs_co_variant.resume", "cs_co_variant.destroy"]);
        assert_eq!(names, expected);
        let first = &fs[0].instructions[0];
        assert_eq!((first.offset, first.mnemonic.as_str(), first.operands.as_str()), (0, "pushq", "%rbp"));
        let last = fs[0].instructions.last().unwrap();
        assert_eq!((last.offset, last.mnemonic.as_str(), last.operands.as_str()), (0xde, "retq", ""));
        assert!(fs.iter().all(|f| !f.truncated));
    }

    #[test]
    fn counts_as_the_independent_awk_count_does() {
        let fs = parse(DUMP).unwrap();
        let s = |n| stats(function(&fs, n));
        // count.awk: instructions=47 vector_spills=5 stack_stores=0 vector_reloads=10
        // folded_reloads=0 ... calls=2 table_calls=1 host_calls=0 stack_bytes=352; loads by an
        // script of their own (a memory operand whose base is not %rsp/%rbp; a broadcast whose
        // register a blend of the next 8 instructions reads is a lane load): none in the first
        // `sample`, cs_co_variant's lane loads 56 (24 inserts, 32 blended broadcasts) and
        // broadcast loads 8, no gathers
        let want = AsmStats {
            instructions: 47,
            vector_spills: 5,
            vector_reloads: 10,
            calls: 2,
            table_calls: 1,
            stack_bytes: 352,
            ..Default::default()
        };
        assert_eq!(s("sample"), want);
        let want = AsmStats {
            instructions: 97,
            calls: 4,
            table_calls: 2,
            host_calls: 2,
            stack_bytes: 72,
            ..Default::default()
        };
        assert_eq!(s("cs_variant"), want);
        let want = AsmStats {
            instructions: 2432,
            vector_spills: 145,
            stack_stores: 128,
            vector_reloads: 206,
            folded_reloads: 17,
            mask_spills: 2,
            mask_reloads: 2,
            calls: 12,
            table_calls: 11,
            host_calls: 1,
            stack_bytes: 5696,
            gathers: 0,
            lane_loads: 56,
            broadcast_loads: 8,
        };
        assert_eq!(s("cs_co_variant"), want);
        let k = kernel(&fs).unwrap();
        assert_eq!(k.total.instructions, 97 + 2432 + 1 + 1);
        assert_eq!((k.total.calls, k.total.table_calls, k.helper_calls), (16, 13, 11));
        assert_eq!(k.total.stack_bytes, 5696);
    }

    /// Real lines of the dump above (`cs_co_variant`, offsets 0x1706-0x17bb and 0x167d), counted
    /// by hand.
    const EXCERPT: &str = "cs_co_variant:
  167d:\tkmovw\t%k2, 224(%rsp)
  1706:\tmovabsq\t$140034419425368, %rbx
  1710:\tvbroadcastss\t(%rbx), %ymm0
  1715:\tvdivps\t%ymm4, %ymm0, %ymm1
  1719:\tvmovaps\t%ymm1, 1312(%rsp)
  1722:\tvdivps\t%ymm5, %ymm0, %ymm1
  1726:\tvmovaps\t%ymm1, 1280(%rsp)
  1745:\tmovq\t16(%r15), %rdi
  1749:\tmovq\t760(%rdi), %rax
  1750:\taddq\t$512, %rdi
  1757:\tmovq\t40(%rax), %rax
  175b:\tvxorps\t%xmm0, %xmm0, %xmm0
  175f:\tcallq\t*(%rax)
  1761:\tvmovaps\t%ymm0, 352(%rsp)
  17ac:\tvmovaps\t288(%rsp), %ymm12
  17bb:\tvmovaps\t352(%rsp), %ymm4
  1a68:\tvandps\t384(%rsp), %ymm2, %ymm0
  1fe0:\tvcmpgeps\t192(%rsp), %ymm2, %k2
  25d6:\tcmovel\t3616(%rsp,%rcx,4), %eax
";

    #[test]
    fn counts_a_hand_checked_excerpt() {
        let fs = parse(EXCERPT).unwrap();
        let s = stats(&fs[0]);
        // 19 instructions; stores to 1312, 1280 and 352 (%rsp): only 352 is read back at a fixed
        // offset here (0x17bb), so 1 spill and 2 stack stores; reloads from 288 and 352: 2;
        // vandps and vcmpgeps read slots: 2 folded; kmovw to a slot: 1 mask spill; the indexed
        // cmovel is none of these; one call, through memory; vbroadcastss (%rbx): 1 broadcast
        // load.
        let want = AsmStats {
            instructions: 19,
            vector_spills: 1,
            stack_stores: 2,
            vector_reloads: 2,
            folded_reloads: 2,
            mask_spills: 1,
            calls: 1,
            table_calls: 1,
            broadcast_loads: 1,
            ..Default::default()
        };
        assert_eq!(s, want);
        assert_eq!(kernel(&fs).unwrap().helper_calls, 1);
        assert_eq!(kernel(&parse("sample:\n     0:\tretq\n").unwrap()), None);
    }

    #[test]
    fn loads_are_told_apart_by_how_they_fill_the_lanes() {
        // Two hardware gathers (one masked, AVX-512), four lane loads (memory sources only:
        // the register insert and the stack-slot insert are not; the broadcast at 0x42 is
        // blended into one lane of %ymm5 at 0x4c), two broadcast loads (the register broadcast
        // and the stack-slot broadcast are not; no blend takes a lane of %ymm4).
        let text = "cs_co_variant:\n\
            \x20    0:\tvpgatherdd\t%ymm1, (%rax,%ymm2,4), %ymm3\n\
            \x20    6:\tvgatherdps\t(%rax,%zmm2,4), %zmm3 {%k1}\n\
            \x20    c:\tvpinsrd\t$1, (%rcx), %xmm0, %xmm0\n\
            \x20   12:\tvinsertps\t$16, 4(%rdx,%rsi), %xmm0, %xmm0\n\
            \x20   18:\tpinsrq\t$1, 8(%rdi), %xmm1\n\
            \x20   1e:\tvpinsrd\t$2, %eax, %xmm0, %xmm0\n\
            \x20   24:\tvpinsrd\t$3, 16(%rsp,%rcx,4), %xmm0, %xmm0\n\
            \x20   2a:\tvpbroadcastd\t(%r8), %ymm4\n\
            \x20   30:\tvbroadcastss\t12(%r9), %zmm5\n\
            \x20   36:\tvpbroadcastd\t%xmm4, %ymm4\n\
            \x20   3c:\tvbroadcastss\t32(%rsp), %ymm6\n\
            \x20   42:\tvpbroadcastd\t(%rax,%rsi,4), %ymm2\n\
            \x20   48:\tjmp\t4\n\
            \x20   4a:\tvpxor\t%xmm2, %xmm2, %xmm2\n\
            \x20   4c:\tvpblendd\t$16, %ymm2, %ymm5, %ymm5\n\
            \x20   52:\tvpblendd\t$1, %ymm9, %ymm5, %ymm5\n";
        let s = stats(&parse(text).unwrap()[0]);
        assert_eq!((s.gathers, s.lane_loads, s.broadcast_loads), (2, 4, 2), "{s:?}");
    }

    #[test]
    fn operands_split_outside_parentheses() {
        assert_eq!(operands("8(%rsp,%rax,4), %ymm0"), ["8(%rsp,%rax,4)", "%ymm0"]);
        assert_eq!(operands("%ymm1, %ymm4 {%k3}"), ["%ymm1", "%ymm4 {%k3}"]);
        assert!(operands("").is_empty());
    }

    #[test]
    fn indexed_and_other_base_memory_is_no_stack_slot() {
        assert!(is_stack_slot("128(%rsp)") && is_stack_slot("(%rsp)") && is_stack_slot("-64(%rbp)"));
        assert!(!is_stack_slot("8(%rsp,%rax,4)") && !is_stack_slot("128(%rbx)"));
        let f = |lines: &[(&str, &str)]| FunctionDump {
            name: "f".into(),
            instructions: lines
                .iter()
                .map(|(m, o)| Instruction { offset: 0, mnemonic: (*m).into(), operands: (*o).into() })
                .collect(),
            truncated: false,
        };
        let reload = ("vmovaps", "32(%rsp), %ymm5");
        assert_eq!(stats(&f(&[("vmovaps", "%ymm0, 32(%rbx)")])).vector_spills, 0);
        assert_eq!(stats(&f(&[("vmovaps", "%ymm0, 32(%rsp,%rax)")])).vector_spills, 0);
        assert_eq!(stats(&f(&[("vmovss", "%xmm0, 32(%rsp)"), reload])).vector_spills, 0, "a scalar");
        assert_eq!(stats(&f(&[("vmovss", "32(%rsp), %xmm0")])).folded_reloads, 0, "a scalar");
        assert_eq!(stats(&f(&[("vmovdqu64", "%zmm3, 32(%rsp)"), reload])).vector_spills, 1);
        assert_eq!(stats(&f(&[("vmovaps", "%ymm0, 32(%rsp) {%k1}"), reload])).vector_spills, 1);
        assert_eq!(stats(&f(&[("vmovaps", "%ymm0, 32(%rsp)"), ("leaq", "32(%rsp), %rax")])).stack_stores, 1);
        assert_eq!(stats(&f(&[("vbroadcastss", "12(%rsp), %ymm0")])).folded_reloads, 1);
        assert_eq!(stats(&f(&[("addl", "12(%rsp), %eax")])).folded_reloads, 0, "no vector register");
        let moved = stats(&f(&[("vmovaps", "%ymm1, %ymm4 {%k3}")]));
        assert_eq!(moved, AsmStats { instructions: 1, ..Default::default() });
    }

    #[test]
    fn host_calls_need_the_address_loaded_into_the_called_register() {
        let fs = parse("f:\n 0:\tmovabsq\t$1, %rax\n a:\tcallq\t*%rax\n c:\tmovabsq\t$1, %rcx\n 16:\tcallq\t*%rax\n")
            .unwrap();
        let s = stats(&fs[0]);
        assert_eq!((s.calls, s.host_calls, s.table_calls), (2, 1, 0));
    }

    #[test]
    fn truncation_and_malformed_dumps_are_reported() {
        let fs = parse("f:\n     0:\tnop\ninvalid\n").unwrap();
        assert!(fs[0].truncated);
        let fs = parse("cs_variant:\n     0:\tnop\ndisassembly larger than 98304 bytes, aborting\n").unwrap();
        assert!(kernel(&fs).unwrap().truncated);
        assert!(parse("     0:\tnop\n").unwrap_err().contains("before any function"));
        assert!(parse("f:\ng:\n     0:\tnop\n").unwrap_err().contains("`f` has no instructions"));
    }

    #[test]
    fn compute_shader_functions_are_told_from_helpers() {
        for n in ["cs_variant", "cs_co_variant", "cs_co_variant.resume", "cs_co_variant.destroy"] {
            assert!(is_compute_shader(n), "{n}");
        }
        for n in ["sample", "image", "size", "fs_variant"] {
            assert!(!is_compute_shader(n), "{n}");
        }
    }
}
