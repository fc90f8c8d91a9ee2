//! The shaders and Rust agree on every shared struct, read from the
//! compiled SPIR-V itself: for each struct of the contract (izb-contract)
//! that a shader module declares, every member's name, byte offset
//! (`OpMemberDecorate … Offset`) and size (from its SPIR-V type) must equal
//! Rust's `offset_of!` / `size_of`. The GLSL is generated from the Rust
//! declaration, so this guards the generator, the include path and the
//! scalar block layout; a shader that declared its own copy of a struct
//! would be caught too. (Structs used only as local values have no
//! layout in SPIR-V and are not compared.)

use std::collections::HashMap;

/// The parts of a SPIR-V module this test needs.
#[derive(Default)]
struct Module {
    names: HashMap<u32, String>,
    member_names: HashMap<(u32, u32), String>,
    member_offsets: HashMap<(u32, u32), u32>,
    array_strides: HashMap<u32, u32>,
    /// Type id → its definition (opcode, operands).
    types: HashMap<u32, (u16, Vec<u32>)>,
    /// Constant id → its 32-bit value.
    constants: HashMap<u32, u32>,
}

/// A SPIR-V literal string (UTF-8, NUL-terminated, packed in words).
fn string(words: &[u32]) -> String {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

fn parse(bytes: &[u8]) -> Module {
    let words: Vec<u32> = bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(words[0], 0x0723_0203, "not SPIR-V");
    let mut m = Module::default();
    let mut i = 5;
    while i < words.len() {
        let (count, op) = ((words[i] >> 16) as usize, (words[i] & 0xFFFF) as u16);
        assert!(count > 0 && i + count <= words.len(), "malformed SPIR-V");
        let ops = &words[i + 1..i + count];
        match op {
            5 => {
                m.names.insert(ops[0], string(&ops[1..]));
            }
            6 => {
                m.member_names.insert((ops[0], ops[1]), string(&ops[2..]));
            }
            // OpDecorate ArrayStride.
            71 if ops[1] == 6 => {
                m.array_strides.insert(ops[0], ops[2]);
            }
            // OpMemberDecorate Offset.
            72 if ops[2] == 35 => {
                m.member_offsets.insert((ops[0], ops[1]), ops[3]);
            }
            // OpTypeInt, OpTypeFloat, OpTypeVector, OpTypeArray, OpTypeStruct.
            21 | 22 | 23 | 28 | 30 => {
                m.types.insert(ops[0], (op, ops[1..].to_vec()));
            }
            // OpConstant (32-bit).
            43 if ops.len() == 3 => {
                m.constants.insert(ops[1], ops[2]);
            }
            _ => {}
        }
        i += count;
    }
    m
}

impl Module {
    /// Bytes of type `id` in the scalar block layout.
    fn size(&self, id: u32) -> usize {
        let (op, ops) = &self.types[&id];
        match op {
            21 | 22 => ops[0] as usize / 8,
            23 => self.size(ops[0]) * ops[1] as usize,
            28 => {
                let stride = self
                    .array_strides
                    .get(&id)
                    .map_or_else(|| self.size(ops[0]), |&s| s as usize);
                stride * self.constants[&ops[1]] as usize
            }
            30 => {
                let last = ops.len() as u32 - 1;
                self.member_offsets[&(id, last)] as usize + self.size(ops[last as usize])
            }
            _ => unreachable!(),
        }
    }
}

#[test]
fn every_shared_struct_has_rusts_layout_in_every_shader() {
    let structs = izb_contract::shared_structs();
    let mut members_checked = 0;
    let mut found: HashMap<&str, usize> = HashMap::new();
    for (module_name, bytes) in izb::gpu::SPIRV_MODULES {
        let m = parse(bytes);
        for (&id, (op, member_types)) in &m.types {
            if *op != 30 {
                continue;
            }
            let Some(name) = m.names.get(&id) else {
                continue;
            };
            let Some((glsl_name, rust_size, members)) = structs.iter().find(|(n, _, _)| n == name)
            else {
                continue;
            };
            // Only the declared struct, not a block that wraps it, and only
            // its laid-out copy: glslang also emits an undecorated copy for
            // a struct used as a local value, which has no memory layout.
            if member_types.len() != members.len() || !m.member_offsets.contains_key(&(id, 0)) {
                continue;
            }
            for (k, rust) in members.iter().enumerate() {
                let k32 = k as u32;
                let what = format!("{module_name}: {glsl_name}.{}", rust.name);
                assert_eq!(
                    m.member_names.get(&(id, k32)).map(String::as_str),
                    Some(rust.name),
                    "{what}: member {k} is named differently"
                );
                assert_eq!(
                    m.member_offsets.get(&(id, k32)).copied(),
                    Some(rust.offset as u32),
                    "{what}: offset"
                );
                assert_eq!(m.size(member_types[k]), rust.size, "{what}: size");
                members_checked += 1;
            }
            assert_eq!(m.size(id), *rust_size, "{module_name}: {glsl_name} size");
            *found.entry(glsl_name).or_default() += 1;
        }
    }
    println!("checked {members_checked} members; structs found per module: {found:?}");
    for (name, _, _) in &structs {
        assert!(found.contains_key(name), "no shader declares {name}");
    }
    assert!(
        members_checked > 100,
        "only {members_checked} members checked"
    );
}
