//! The two declaration macros: constants and structs, each written once in
//! Rust and rendered to GLSL by [`crate::glsl_header`].

/// How a constant is spelled in GLSL.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GlslKind {
    /// A signed literal (`7`): bindings, array indices and sizes.
    Int,
    /// An unsigned literal (`7u`): bit masks and `uint` values.
    Uint,
    /// A `float`, exact: the decimal shortest form when glslang's
    /// parse-as-double-then-round gives the same bits, else
    /// `uintBitsToFloat(0x…u)`.
    Float,
}

/// One `#define`: its GLSL name and literal.
#[derive(Clone, Debug)]
pub struct GlslConstant {
    pub name: &'static str,
    pub literal: String,
}

/// The GLSL literal of `value` spelled as `kind`.
pub fn literal(kind: GlslKind, value: f64) -> String {
    match kind {
        GlslKind::Int => format!("{}", value as i64),
        GlslKind::Uint => format!("{}u", value as u64),
        GlslKind::Float => {
            let f = value as f32;
            let decimal = format!("{f:?}");
            // glslang reads a float literal as a double, then rounds.
            if decimal.parse::<f64>().map(|d| d as f32) == Ok(f) {
                decimal
            } else {
                format!("uintBitsToFloat(0x{:08x}u)", f.to_bits())
            }
        }
    }
}

/// Declares a group of constants once: a Rust module of `pub const`s and
/// its `glsl()` list of `#define PREFIX_NAME literal`.
macro_rules! shared_constants {
    (
        $(#[$m:meta])*
        pub mod $module:ident: $t:ty as $kind:ident, prefix $prefix:literal {
            $( $(#[$fm:meta])* $name:ident = $value:expr; )*
        }
    ) => {
        $(#[$m])*
        pub mod $module {
            $( $(#[$fm])* pub const $name: $t = $value; )*

            /// The `#define`s of this group, in declaration order.
            pub fn glsl() -> Vec<$crate::macros::GlslConstant> {
                vec![$($crate::macros::GlslConstant {
                    name: concat!($prefix, stringify!($name)),
                    literal: $crate::macros::literal(
                        $crate::macros::GlslKind::$kind,
                        $name as f64,
                    ),
                }),*]
            }
        }
    };
}
pub(crate) use shared_constants;

/// One member of a shared struct: its name, GLSL declaration, and where
/// Rust puts it.
#[derive(Clone, Copy, Debug)]
pub struct Member {
    pub name: &'static str,
    /// `type name[size]` as the GLSL struct declares it.
    pub glsl: &'static str,
    pub offset: usize,
    pub size: usize,
}

/// A struct both sides declare: `#[repr(C)]` + bytemuck in Rust, and the
/// GLSL struct [`crate::glsl_header`] emits from the same member list.
pub trait SharedStruct {
    /// The struct's name in GLSL.
    const GLSL_NAME: &'static str;
    /// Rust's size of the whole struct.
    const SIZE: usize;
    /// The members in declaration order.
    fn members() -> Vec<Member>;
}

/// Declares a struct once: the Rust struct and its [`SharedStruct`] impl
/// (each member with its GLSL declaration).
macro_rules! shared_struct {
    (
        $(#[$m:meta])*
        pub struct $name:ident as $glsl_name:literal {
            $( $(#[$fm:meta])* pub $field:ident: $t:ty => $decl:literal, )*
        }
    ) => {
        $(#[$m])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
        pub struct $name {
            $( $(#[$fm])* pub $field: $t, )*
        }

        impl $crate::macros::SharedStruct for $name {
            const GLSL_NAME: &'static str = $glsl_name;
            const SIZE: usize = std::mem::size_of::<$name>();
            fn members() -> Vec<$crate::macros::Member> {
                vec![$($crate::macros::Member {
                    name: stringify!($field),
                    glsl: $decl,
                    offset: std::mem::offset_of!($name, $field),
                    size: std::mem::size_of::<$t>(),
                }),*]
            }
        }
    };
}
pub(crate) use shared_struct;
