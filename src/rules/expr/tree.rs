//! A compiled expression read back as a tree, for static analysis (`graftal
//! lint`). The stack machine's op vector is decompiled, so the tree is exactly
//! what runs: constants already folded, `&&`/`||` with their operands.

use super::{Binary, Expr, Ternary, Unary};

/// An operand an instruction pushes or fuses.
#[derive(Debug, Clone, Copy)]
pub(super) enum Operand {
    /// Index into the constant pool.
    Const(u32),
    Slot(u32),
}

/// One instruction, by operation.
#[derive(Debug, Clone, Copy)]
pub(super) enum Decoded {
    Push(Operand),
    /// `&&` (`and`) or `||`: the right operand is the next `skip` instructions.
    Logic {
        and: bool,
        skip: u32,
    },
    Unary(Unary),
    /// A binary operation; its right operand is fused when `Some`.
    Binary(Binary, Option<Operand>),
    Ternary(Ternary),
}

/// An expression tree. Values follow [`Expr::eval`]: `And`/`Or` yield 0 or 1.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Tree {
    Const(f64),
    Slot(u32),
    Unary(Unary, Box<Tree>),
    Binary(Binary, Box<Tree>, Box<Tree>),
    Ternary(Ternary, Box<Tree>, Box<Tree>, Box<Tree>),
    And(Box<Tree>, Box<Tree>),
    Or(Box<Tree>, Box<Tree>),
}

impl Expr {
    /// The expression as a tree (a constant when it was folded).
    pub(crate) fn tree(&self) -> Tree {
        if let Some(value) = self.constant {
            return Tree::Const(value);
        }
        let operand = |o: Operand| match o {
            Operand::Const(i) => Tree::Const(self.constants[i as usize]),
            Operand::Slot(s) => Tree::Slot(s),
        };
        let mut stack: Vec<Tree> = Vec::new();
        // Open `&&`/`||`: (pc where the right operand ends, is `&&`, left).
        let mut open: Vec<(usize, bool, Tree)> = Vec::new();
        let pop = |stack: &mut Vec<Tree>| stack.pop().expect("well-formed op vector");
        for pc in 0..=self.ops.len() {
            while open.last().is_some_and(|(end, _, _)| *end == pc) {
                let (_, and, left) = open.pop().expect("checked");
                let right = Box::new(pop(&mut stack));
                stack.push(if and {
                    Tree::And(Box::new(left), right)
                } else {
                    Tree::Or(Box::new(left), right)
                });
            }
            let Some(&op) = self.ops.get(pc) else { break };
            match op.decoded() {
                Decoded::Push(o) => stack.push(operand(o)),
                Decoded::Logic { and, skip } => {
                    let left = pop(&mut stack);
                    open.push((pc + 1 + skip as usize, and, left));
                }
                Decoded::Unary(f) => {
                    let x = pop(&mut stack);
                    stack.push(Tree::Unary(f, Box::new(x)));
                }
                Decoded::Binary(f, fused) => {
                    let b = match fused {
                        Some(o) => operand(o),
                        None => pop(&mut stack),
                    };
                    let a = pop(&mut stack);
                    stack.push(Tree::Binary(f, Box::new(a), Box::new(b)));
                }
                Decoded::Ternary(f) => {
                    let c = pop(&mut stack);
                    let b = pop(&mut stack);
                    let a = pop(&mut stack);
                    stack.push(Tree::Ternary(f, Box::new(a), Box::new(b), Box::new(c)));
                }
            }
        }
        pop(&mut stack)
    }
}

#[cfg(test)]
impl Tree {
    /// Evaluates the tree with slot values (the same arithmetic as the
    /// stack machine; used to test the decompilation).
    pub(crate) fn eval(&self, slots: &[f64]) -> f64 {
        match self {
            Tree::Const(v) => *v,
            Tree::Slot(s) => slots[*s as usize],
            Tree::Unary(f, x) => f.apply(x.eval(slots)),
            Tree::Binary(f, a, b) => f.apply(a.eval(slots), b.eval(slots)),
            Tree::Ternary(f, a, b, c) => f.apply(a.eval(slots), b.eval(slots), c.eval(slots)),
            Tree::And(a, b) => f64::from(u8::from(a.eval(slots) != 0.0 && b.eval(slots) != 0.0)),
            Tree::Or(a, b) => f64::from(u8::from(a.eval(slots) != 0.0 || b.eval(slots) != 0.0)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::SlotNames;
    use super::*;

    #[test]
    fn decompiled_trees_evaluate_like_the_stack_machine() {
        let names = SlotNames(&["x", "y", "z"]);
        let sources = [
            "x > 1 && x < 0",
            "!(x < -0.5 && abs(y - 0.5) < 0.1) || z",
            "x && (y || z) && !x",
            "clamp(x, y, z) * 2 - min(x, y, 3) ^ 2 % 5",
            "lerp(x, y, z) >= smoothstep(0, 1, x) == (y != z)",
            "(x || y) && (y || z) || x && y && z",
            "-x^2 + atan2(y, x) / (z + 1)",
            "x",
            "1 + 2",
        ];
        let values = [-2.0, -0.5, 0.0, 0.5, 1.0, 3.0];
        for source in sources {
            let expr = Expr::compile(source, &names).unwrap();
            let tree = expr.tree();
            for &x in &values {
                for &y in &values {
                    for &z in &values {
                        let slots = [x, y, z];
                        let (a, b) = (expr.eval(&slots), tree.eval(&slots));
                        assert!(
                            a == b || (a.is_nan() && b.is_nan()),
                            "{source} at {slots:?}: {a} vs {b}"
                        );
                    }
                }
            }
        }
        assert!(matches!(
            Expr::compile("x > 1 && x < 0", &names).unwrap().tree(),
            Tree::And(..)
        ));
    }
}
