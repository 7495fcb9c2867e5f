//! Instruction counts by walking the SPIR-V words (no parser needed: every instruction starts
//! with a word holding its length in the high half and its opcode in the low half).

use rspirv::spirv::Op;
use serde::Serialize;

/// Opcode classes, after the instruction groups of the SPIR-V specification (sec. 3.52).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OpClass {
    /// Arithmetic, bit, relational and logical instructions, and extended instructions
    /// (`OpExtInst`: GLSL.std.450 min, max, fma, sqrt, ...).
    Arithmetic,
    /// Variables, loads, stores, access chains, atomics.
    Memory,
    /// Labels, branches, merges, phis, returns, function calls.
    ControlFlow,
    /// Conversion instructions (`OpConvert*`, `OpBitcast`, ...).
    Conversion,
    /// Image instructions (`OpImageRead`/`OpImageFetch`/`OpImageWrite`, ...): the kernels
    /// read the scene from storage texel buffers, so these are their scene loads.
    Image,
    /// Composite instructions: vector extract/insert/shuffle, composite construct/extract/
    /// insert, copy object, transpose.
    Composite,
    /// Everything else: types, constants, decorations, debug names, function declarations.
    Other,
}

fn between(op: u32, first: Op, last: Op) -> bool {
    (first as u32..=last as u32).contains(&op)
}

pub fn classify(op: u32) -> OpClass {
    if op == Op::ExtInst as u32
        || between(op, Op::SNegate, Op::SMulExtended)
        || between(op, Op::Any, Op::FUnordGreaterThanEqual)
        || between(op, Op::ShiftRightLogical, Op::BitCount)
        || between(op, Op::SDot, Op::SUDotAccSat)
    {
        OpClass::Arithmetic
    } else if between(op, Op::Variable, Op::InBoundsPtrAccessChain) || between(op, Op::AtomicLoad, Op::AtomicXor) {
        OpClass::Memory
    } else if op == Op::FunctionCall as u32
        || between(op, Op::Phi, Op::LifetimeStop)
        || op == Op::TerminateInvocation as u32
    {
        OpClass::ControlFlow
    } else if between(op, Op::ConvertFToU, Op::Bitcast) {
        OpClass::Conversion
    } else if between(op, Op::SampledImage, Op::ImageQuerySamples)
        || between(op, Op::ImageSparseSampleImplicitLod, Op::ImageSparseRead)
    {
        OpClass::Image
    } else if between(op, Op::VectorExtractDynamic, Op::Transpose) || op == Op::CopyLogical as u32 {
        OpClass::Composite
    } else {
        OpClass::Other
    }
}

/// Instructions in a module: all of them, those inside function bodies (`OpFunction` to
/// `OpFunctionEnd` inclusive) and, of the latter, how many fall in each [`OpClass`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct InstructionCounts {
    pub module: u32,
    pub functions: u32,
    pub arithmetic: u32,
    pub memory: u32,
    pub control_flow: u32,
    pub conversion: u32,
    pub image: u32,
    pub composite: u32,
    pub other: u32,
}

/// Counts the instructions of a SPIR-V module given as words.
pub fn count(words: &[u32]) -> Result<InstructionCounts, String> {
    if words.len() < 5 || words[0] != 0x0723_0203 {
        return Err("not a SPIR-V module (bad magic or shorter than the header)".into());
    }
    let mut c = InstructionCounts::default();
    let mut in_function = false;
    let mut i = 5;
    while i < words.len() {
        let len = (words[i] >> 16) as usize;
        let op = words[i] & 0xffff;
        if len == 0 || i + len > words.len() {
            return Err(format!("instruction at word {i} has bad length {len}"));
        }
        c.module += 1;
        if op == Op::Function as u32 {
            in_function = true;
        }
        if in_function {
            c.functions += 1;
            match classify(op) {
                OpClass::Arithmetic => c.arithmetic += 1,
                OpClass::Memory => c.memory += 1,
                OpClass::ControlFlow => c.control_flow += 1,
                OpClass::Conversion => c.conversion += 1,
                OpClass::Image => c.image += 1,
                OpClass::Composite => c.composite += 1,
                OpClass::Other => c.other += 1,
            }
        }
        if op == Op::FunctionEnd as u32 {
            in_function = false;
        }
        i += len;
    }
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inst(op: Op, operands: &[u32]) -> Vec<u32> {
        let mut v = vec![((operands.len() as u32 + 1) << 16) | op as u32];
        v.extend_from_slice(operands);
        v
    }

    #[test]
    fn counts_a_hand_made_module() {
        let mut w = vec![0x0723_0203, 0x0001_0500, 0, 20, 0];
        w.extend(inst(Op::Capability, &[1]));
        w.extend(inst(Op::TypeVoid, &[1]));
        w.extend(inst(Op::Function, &[1, 2, 0, 3]));
        w.extend(inst(Op::Label, &[4]));
        w.extend(inst(Op::FAdd, &[5, 6, 7, 8]));
        w.extend(inst(Op::Load, &[5, 9, 10]));
        w.extend(inst(Op::ConvertFToU, &[11, 12, 13]));
        w.extend(inst(Op::CompositeExtract, &[5, 14, 15, 0]));
        w.extend(inst(Op::ExtInst, &[5, 16, 17, 40, 18]));
        w.extend(inst(Op::FOrdLessThan, &[19, 20, 21, 22]));
        w.extend(inst(Op::ImageRead, &[23, 24, 25, 26]));
        w.extend(inst(Op::VectorShuffle, &[27, 28, 29, 30, 0, 1]));
        w.extend(inst(Op::Return, &[]));
        w.extend(inst(Op::FunctionEnd, &[]));
        let c = count(&w).unwrap();
        assert_eq!(c.module, 14);
        assert_eq!(c.functions, 12);
        assert_eq!((c.arithmetic, c.memory, c.control_flow, c.conversion), (3, 1, 2, 1));
        assert_eq!((c.image, c.composite, c.other), (1, 2, 2));
    }

    #[test]
    fn rejects_truncated_modules() {
        assert!(count(&[0x0723_0203, 0, 0, 0]).is_err());
        let mut w = vec![0x0723_0203, 0x0001_0500, 0, 20, 0];
        w.push((4 << 16) | Op::Capability as u32);
        assert!(count(&w).is_err());
    }
}
