//! Reflection: what a kernel binds (rspirv-reflect) and how its buffer structs are laid out
//! (the `Offset` and `ArrayStride` decorations, read with rspirv).

use std::collections::BTreeMap;

use ash::vk;
use rspirv::dr::Operand;
use rspirv::spirv::{Decoration, Op};

use crate::error::{Error, Result};

#[derive(Clone, Debug)]
pub struct DescriptorBinding {
    pub ty: vk::DescriptorType,
    pub name: String,
}

/// What a compute kernel needs from its pipeline layout.
#[derive(Clone, Debug)]
pub struct KernelInterface {
    /// set -> binding -> descriptor.
    pub sets: BTreeMap<u32, BTreeMap<u32, DescriptorBinding>>,
    /// (offset, size) of the push-constant block.
    pub push_constants: Option<(u32, u32)>,
    /// The workgroup size: the module's default, or after [`KernelInterface::specialize`] the size
    /// the pipeline was created with (what dispatches must use).
    pub local_size: (u32, u32, u32),
    /// Specialisation-constant id of each workgroup dimension that has one
    /// (`layout(local_size_x_id = N)`), x, y, z.
    pub local_size_spec_ids: [Option<u32>; 3],
}

impl KernelInterface {
    /// Applies `(constant_id, value)` pairs, as given at pipeline creation, to the workgroup
    /// size.
    pub fn specialize(&mut self, constants: &[(u32, u32)]) {
        let mut size = [self.local_size.0, self.local_size.1, self.local_size.2];
        for (dim, id) in self.local_size_spec_ids.iter().enumerate() {
            if let Some(&(_, v)) = id.and_then(|id| constants.iter().rev().find(|(c, _)| *c == id)) {
                size[dim] = v;
            }
        }
        self.local_size = (size[0], size[1], size[2]);
    }
}

/// Descriptor sets (set -> binding -> descriptor) of a module.
pub type DescriptorSets = BTreeMap<u32, BTreeMap<u32, DescriptorBinding>>;

pub fn reflect(kernel: &str, words: &[u32]) -> Result<KernelInterface> {
    let err = |m: String| Error::Spirv { kernel: kernel.into(), message: m };
    let r = load(kernel, words)?;
    let (sets, push_constants) = resources(kernel, &r)?;
    let mut local_size = r.get_compute_group_size().ok_or_else(|| err("no LocalSize execution mode".into()))?;
    let mut local_size_spec_ids = [None; 3];
    // A `WorkgroupSize` built-in overrides `LocalSize` (SPIR-V spec, 3.21 BuiltIn); with
    // `local_size_x_id` its components are specialisation constants.
    if let Some(dims) = workgroup_size_builtin(words).map_err(err)? {
        local_size = (dims[0].0, dims[1].0, dims[2].0);
        local_size_spec_ids = [dims[0].1, dims[1].1, dims[2].1];
    }
    Ok(KernelInterface { sets, push_constants, local_size, local_size_spec_ids })
}

/// What any shader stage binds: its descriptor sets and push-constant range (offset, size).
/// [`reflect`] adds a compute kernel's workgroup size; the ray-tracing stages
/// (`gpu::rtpipeline`) have none.
pub fn reflect_stage(stage: &str, words: &[u32]) -> Result<(DescriptorSets, Option<(u32, u32)>)> {
    resources(stage, &load(stage, words)?)
}

fn load(kernel: &str, words: &[u32]) -> Result<rspirv_reflect::Reflection> {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    rspirv_reflect::Reflection::new_from_spirv(&bytes)
        .map_err(|e| Error::Spirv { kernel: kernel.into(), message: format!("{e:?}") })
}

fn resources(kernel: &str, r: &rspirv_reflect::Reflection) -> Result<(DescriptorSets, Option<(u32, u32)>)> {
    let err = |m: String| Error::Spirv { kernel: kernel.into(), message: m };
    let sets = r
        .get_descriptor_sets()
        .map_err(|e| err(format!("{e:?}")))?
        .into_iter()
        .map(|(set, bindings)| {
            let b = bindings
                .into_iter()
                .map(|(binding, info)| {
                    (binding, DescriptorBinding { ty: vk::DescriptorType::from_raw(info.ty.0 as i32), name: info.name })
                })
                .collect();
            (set, b)
        })
        .collect();
    let push_constants = r.get_push_constant_range().map_err(|e| err(format!("{e:?}")))?.map(|p| (p.offset, p.size));
    Ok((sets, push_constants))
}

/// Per workgroup dimension: the default value and the `SpecId` when it is a specialisation
/// constant.
pub type WorkgroupSizeDecl = [(u32, Option<u32>); 3];

/// The `WorkgroupSize` built-in, if the module declares one.
pub fn workgroup_size_builtin(words: &[u32]) -> std::result::Result<Option<WorkgroupSizeDecl>, String> {
    let m = rspirv::dr::load_words(words).map_err(|e| e.to_string())?;
    let mut builtin = None;
    let mut spec_ids: BTreeMap<u32, u32> = BTreeMap::new();
    for i in &m.annotations {
        match (i.class.opcode, i.operands.as_slice()) {
            (
                Op::Decorate,
                [Operand::IdRef(t), Operand::Decoration(Decoration::BuiltIn), Operand::BuiltIn(rspirv::spirv::BuiltIn::WorkgroupSize)],
            ) => builtin = Some(*t),
            (Op::Decorate, [Operand::IdRef(t), Operand::Decoration(Decoration::SpecId), Operand::LiteralBit32(id)]) => {
                spec_ids.insert(*t, *id);
            }
            _ => {}
        }
    }
    let Some(builtin) = builtin else {
        return Ok(None);
    };
    let defs: BTreeMap<u32, &rspirv::dr::Instruction> =
        m.types_global_values.iter().filter_map(|i| i.result_id.map(|id| (id, i))).collect();
    let composite = defs.get(&builtin).ok_or("WorkgroupSize decorates no constant")?;
    if !matches!(composite.class.opcode, Op::ConstantComposite | Op::SpecConstantComposite) {
        return Err(format!("WorkgroupSize is a {:?}, not a constant composite", composite.class.opcode));
    }
    let mut dims = [(1, None); 3];
    for (dim, op) in composite.operands.iter().take(3).enumerate() {
        let Operand::IdRef(c) = op else {
            return Err("WorkgroupSize component is not an id".into());
        };
        let value = match defs.get(c).map(|d| (d.class.opcode, d.operands.first())) {
            Some((Op::Constant | Op::SpecConstant, Some(Operand::LiteralBit32(v)))) => *v,
            other => return Err(format!("WorkgroupSize component {c} is not a 32-bit constant ({other:?})")),
        };
        dims[dim] = (value, spec_ids.get(c).copied());
    }
    Ok(Some(dims))
}

/// Whether the module reads a lane's place in its subgroup: the `SubgroupSize` or
/// `SubgroupLocalInvocationId` built-in (`gl_SubgroupSize`, `gl_SubgroupInvocationID`). Such a
/// kernel hands work to lanes by index (glsl/raycast_coop.comp), so every lane of its subgroups
/// must be active: `gpu::Context` creates it with full subgroups.
pub fn reads_subgroup_lanes(words: &[u32]) -> std::result::Result<bool, String> {
    use rspirv::spirv::BuiltIn;
    let m = rspirv::dr::load_words(words).map_err(|e| e.to_string())?;
    Ok(m.annotations.iter().any(|i| {
        matches!(
            (i.class.opcode, i.operands.as_slice()),
            (
                Op::Decorate,
                [
                    _,
                    Operand::Decoration(Decoration::BuiltIn),
                    Operand::BuiltIn(BuiltIn::SubgroupSize | BuiltIn::SubgroupLocalInvocationId)
                ],
            )
        )
    }))
}

/// The layout of the runtime array a storage buffer (or the push-constant block) holds, as the
/// SPIR-V declares it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BufferLayout {
    /// `ArrayStride` of the block's runtime-array member (`None` for a plain block).
    pub array_stride: Option<u32>,
    /// `Offset` of each member of the array element if it is a struct (or of the block itself
    /// when it holds no array).
    pub member_offsets: Vec<u32>,
}

/// Layout of every storage buffer by binding (set 0), plus the push-constant block under
/// `u32::MAX` (images and other descriptors are not listed). Shaderc's performance level strips debug names, so structs are found through
/// the variables' `Binding` decorations, not by name.
pub fn buffer_layouts(words: &[u32]) -> std::result::Result<BTreeMap<u32, BufferLayout>, String> {
    let m = rspirv::dr::load_words(words).map_err(|e| e.to_string())?;
    let lit = |o: &Operand| match o {
        Operand::LiteralBit32(x) => Some(*x),
        _ => None,
    };
    let idref = |o: &Operand| match o {
        Operand::IdRef(i) => Some(*i),
        _ => None,
    };
    let mut offsets: BTreeMap<u32, BTreeMap<u32, u32>> = BTreeMap::new();
    let mut strides: BTreeMap<u32, u32> = BTreeMap::new();
    let mut binding_of: BTreeMap<u32, u32> = BTreeMap::new();
    for i in &m.annotations {
        match (i.class.opcode, i.operands.as_slice()) {
            (Op::MemberDecorate, [t, idx, Operand::Decoration(Decoration::Offset), off]) => {
                let (Some(t), Some(idx), Some(off)) = (idref(t), lit(idx), lit(off)) else {
                    continue;
                };
                offsets.entry(t).or_default().insert(idx, off);
            }
            (Op::Decorate, [t, Operand::Decoration(Decoration::ArrayStride), s]) => {
                if let (Some(t), Some(s)) = (idref(t), lit(s)) {
                    strides.insert(t, s);
                }
            }
            (Op::Decorate, [t, Operand::Decoration(Decoration::Binding), b]) => {
                if let (Some(t), Some(b)) = (idref(t), lit(b)) {
                    binding_of.insert(t, b);
                }
            }
            _ => {}
        }
    }
    let defs: BTreeMap<u32, &rspirv::dr::Instruction> =
        m.types_global_values.iter().filter_map(|i| i.result_id.map(|id| (id, i))).collect();
    let struct_offsets = |id: u32| -> Vec<u32> {
        let n = defs.get(&id).filter(|d| d.class.opcode == Op::TypeStruct).map_or(0, |d| d.operands.len());
        (0..n as u32).map(|k| offsets.get(&id).and_then(|o| o.get(&k)).copied().unwrap_or(u32::MAX)).collect()
    };
    let layout_of_block = |block: u32| -> BufferLayout {
        let first = defs.get(&block).and_then(|d| d.operands.first()).and_then(idref);
        match first.and_then(|f| defs.get(&f).map(|d| (f, d))) {
            Some((arr, d)) if d.class.opcode == Op::TypeRuntimeArray => BufferLayout {
                array_stride: strides.get(&arr).copied(),
                member_offsets: d.operands.first().and_then(idref).map(struct_offsets).unwrap_or_default(),
            },
            _ => BufferLayout { array_stride: None, member_offsets: struct_offsets(block) },
        }
    };
    let mut out = BTreeMap::new();
    for i in &m.types_global_values {
        if i.class.opcode != Op::Variable {
            continue;
        }
        let (Some(var), Some(ptr)) = (i.result_id, i.result_type) else {
            continue;
        };
        let class = i.operands.first();
        // Pointer type: OpTypePointer <storage class> <pointee>.
        let Some(pointee) = defs.get(&ptr).and_then(|p| p.operands.get(1)).and_then(idref) else {
            continue;
        };
        match class {
            Some(Operand::StorageClass(
                rspirv::spirv::StorageClass::StorageBuffer | rspirv::spirv::StorageClass::Uniform,
            )) => {
                if let Some(&b) = binding_of.get(&var) {
                    out.insert(b, layout_of_block(pointee));
                }
            }
            Some(Operand::StorageClass(rspirv::spirv::StorageClass::PushConstant)) => {
                out.insert(u32::MAX, layout_of_block(pointee));
            }
            _ => {}
        }
    }
    Ok(out)
}
