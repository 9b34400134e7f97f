//! A formula's value in `f64`, as the generated functions compute it.

use super::{Cmp, Expr, Func, Node, Op, Power};

impl Expr {
    /// The value for `inputs` (by index), in `f64`; `None` where a
    /// comparison meets a NaN. A non-finite number is returned as such.
    pub fn eval(&self, inputs: &[f64]) -> Option<f64> {
        Some(match &self.node {
            Node::Num(v) | Node::Const(_, v) => *v,
            Node::Input(i, _) => *inputs.get(*i)?,
            Node::Name(_) | Node::Cmp(..) => return None,
            Node::Neg(x) => -x.eval(inputs)?,
            Node::Bin(op, a, b) => {
                let power = (*op == Op::Pow).then(|| Power::of(a, b));
                let (a, b) = (a.eval(inputs)?, b.eval(inputs)?);
                match (op, power) {
                    (Op::Add, _) => a + b,
                    (Op::Sub, _) => a - b,
                    (Op::Mul, _) => a * b,
                    (Op::Div, _) => a / b,
                    (Op::Pow, Some(Power::Whole(n))) => yosemitech_rtu::derived::powi(a, n),
                    (Op::Pow, Some(Power::OfNumber { base, ln_base })) => {
                        yosemitech_rtu::derived::pow_positive(base, ln_base, b)
                    }
                    (Op::Pow, Some(Power::General) | None) => a.powf(b),
                }
            }
            Node::Call(Func::Exp, x) => x.eval(inputs)?.exp(),
            Node::Call(Func::Ln, x) => x.eval(inputs)?.ln(),
            Node::If(c, a, b) => {
                if c.condition(inputs)? {
                    a.eval(inputs)?
                } else {
                    b.eval(inputs)?
                }
            }
        })
    }

    fn condition(&self, inputs: &[f64]) -> Option<bool> {
        let Node::Cmp(op, a, b) = &self.node else { return None };
        let (a, b) = (a.eval(inputs)?, b.eval(inputs)?);
        if a.is_nan() || b.is_nan() { None } else { Some(op.holds(a, b)) }
    }
}

impl Cmp {
    fn holds(self, a: f64, b: f64) -> bool {
        match self {
            Cmp::Lt => a < b,
            Cmp::Le => a <= b,
            Cmp::Gt => a > b,
            Cmp::Ge => a >= b,
            Cmp::Eq => a == b,
            Cmp::Ne => a != b,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::run;

    #[test]
    fn precedence_and_values() {
        assert_eq!(run("1 + 2 * 3", None, &[]), Ok(Some(7.0)));
        assert_eq!(run("(1 + 2) * 3", None, &[]), Ok(Some(9.0)));
        assert_eq!(run("-2^2", None, &[]), Ok(Some(-4.0)));
        assert_eq!(run("2^3^2", None, &[]), Ok(Some(512.0)));
        assert_eq!(run("2^-1", None, &[]), Ok(Some(0.5)));
        assert_eq!(run("8 / 4 / 2", None, &[]), Ok(Some(1.0)));
        assert_eq!(run("10 - 4 - 3", None, &[]), Ok(Some(3.0)));
        assert_eq!(run("1.5e3 + .5", None, &[]), Ok(Some(1500.5)));
        assert_eq!(run("ln(exp(2))", None, &[]), Ok(Some(2.0)));
        assert_eq!(run("if(t < 0, 0, t)", Some("degC"), &[0.0, -5.0]), Ok(Some(0.0)));
        assert_eq!(run("if(t >= 0, t, 0)", Some("degC"), &[0.0, 5.0]), Ok(Some(5.0)));
        assert_eq!(run("if(t == 2, 1, 0) + if(t != 2, 10, 20)", None, &[0.0, 2.0]), Ok(Some(21.0)));
        assert_eq!(run("c * k", Some("mg/L"), &[2.0]), Ok(Some(1.0)));
        // A NaN in a comparison has no value.
        assert_eq!(run("if(t > 1, 1, 2)", None, &[0.0, f64::NAN]), Ok(None));
    }
}
