// composite.hpp — a composite of the field algebra as one program for a device: its operator
// tree flattened to postfix over its leaves, which evaluate into buffers of their own (each by
// its device program, or on the CPU) before one pass (field_combine.comp) combines them.
// Private to the library.
#pragma once

#include <gsd/field.hpp>

#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

namespace gsd::field {

/// One step of the postfix program (a vec4 for the shader).
struct CombineOp {
    float code;   ///< OpCode
    float leaf;   ///< kLeaf: which leaf's results to push
    float param;  ///< the smooth radius k (Booleans) or r (offset, shell)
    float unused = 0;
};
enum OpCode : int { kLeaf = 0, kUnion = 1, kIntersection = 2, kDifference = 3, kOffset = 4, kShell = 5 };
/// The shader's stack (field_combine.comp): deeper composites evaluate on the CPU.
inline constexpr int kMaxStack = 16;

/// An operator of the field algebra: a Field whose device program is its flattened tree.
class OperatorField : public Field {
public:
    /// Appends this subtree in postfix: operands, then this operator.
    virtual void flatten(std::vector<CombineOp>& ops, std::vector<const Field*>& leaves) const = 0;
    /// The composite's program, built on first use: none when no leaf has a device program (all
    /// would evaluate on the CPU anyway) or the tree is deeper than kMaxStack.
    const DeviceProgram* device_program() const override;

protected:
    /// Appends an operand: an operator's subtree, or a leaf.
    static void flatten_operand(const Field& f, std::vector<CombineOp>& ops, std::vector<const Field*>& leaves);

private:
    mutable std::once_flag once_;
    mutable std::shared_ptr<const DeviceProgram> program_;
};

/// The program over `leaves` (field_gpu.cpp; nullptr in a build without Vulkan). The leaves
/// must outlive it (the composite that owns it holds them).
std::shared_ptr<const DeviceProgram> make_composite_program(std::vector<CombineOp> ops, std::vector<const Field*> leaves);

}  // namespace gsd::field
