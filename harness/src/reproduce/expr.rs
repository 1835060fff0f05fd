//! The small arithmetic language of a spec's `ours` and `reason` fields.
//!
//! ```text
//! expr   := term (('+' | '-') term)*
//! term   := factor (('*' | '/') factor)*
//! factor := number | ref | '-' factor | '(' expr ')' | name '(' args ')'
//! ref    := measure '.' key ('.' key)*        e.g. build.interior_per_leaf,
//!                                             fig1.eps_15.median.points_drawn
//! ```
//!
//! A reference names a measure of the spec and one of its metrics (see
//! [`super::exec`] for what each kind of measure provides); segments are letters, digits and
//! `_`. Numbers may use `_` separators and an exponent (`1_000`, `2.5e6`). Functions:
//! `min(a, b)`, `max(a, b)`, `abs(a)`, and `points_at_flip(sweep, flip)` — the median points
//! drawn at which the sweep measure `sweep` reaches the mean FLIP `flip`, interpolated
//! linearly in log–log between its two neighbouring targets (an error outside its range).

use std::fmt;

/// A parsed expression.
#[derive(Debug, Clone, PartialEq)]
pub enum Expr {
    /// A literal.
    Num(f64),
    /// `measure.key…`: the measure's id and the metric key (the rest, dots included).
    Ref {
        /// Measure id.
        measure: String,
        /// Metric key.
        key: String,
    },
    /// Unary minus.
    Neg(Box<Expr>),
    /// A binary operation.
    Bin(Box<Expr>, Op, Box<Expr>),
    /// A function call.
    Call(Func, Vec<Expr>),
}

/// Binary operators.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Op {
    /// `+`
    Add,
    /// `-`
    Sub,
    /// `*`
    Mul,
    /// `/`
    Div,
}

/// Built-in functions.
#[derive(Debug, Clone, PartialEq)]
pub enum Func {
    /// `min(a, b)`
    Min,
    /// `max(a, b)`
    Max,
    /// `abs(a)`
    Abs,
    /// `points_at_flip(sweep, flip)`: the first argument is a measure id.
    PointsAtFlip(String),
}

/// What evaluating an expression needs: metric values and sweep curves.
pub trait Env {
    /// The value of `measure`'s metric `key`.
    fn metric(&self, measure: &str, key: &str) -> Result<f64, String>;
    /// `(FLIP, points)` per target of the sweep measure `measure`.
    fn curve(&self, measure: &str) -> Result<Vec<(f64, f64)>, String>;
}

impl Expr {
    /// Parses `text`; errors say what was expected where.
    pub fn parse(text: &str) -> Result<Expr, String> {
        let mut p = Parser {
            s: text.as_bytes(),
            i: 0,
            text,
        };
        let e = p.expr()?;
        p.ws();
        if p.i < p.s.len() {
            return Err(p.err("an operator or the end"));
        }
        Ok(e)
    }

    /// The measures the expression refers to (with repeats), including sweep arguments.
    pub fn measures(&self) -> Vec<&str> {
        let mut out = Vec::new();
        self.visit(&mut |e| match e {
            Expr::Ref { measure, .. } => out.push(measure.as_str()),
            Expr::Call(Func::PointsAtFlip(m), _) => out.push(m.as_str()),
            _ => {}
        });
        out
    }

    /// The `(measure, key)` pairs the expression reads (with repeats; not sweep arguments,
    /// which read a sweep's image error and points, never a time).
    pub fn refs(&self) -> Vec<(&str, &str)> {
        let mut out = Vec::new();
        self.visit(&mut |e| {
            if let Expr::Ref { measure, key } = e {
                out.push((measure.as_str(), key.as_str()));
            }
        });
        out
    }

    fn visit<'a>(&'a self, f: &mut impl FnMut(&'a Expr)) {
        f(self);
        match self {
            Expr::Neg(a) => a.visit(f),
            Expr::Bin(a, _, b) => {
                a.visit(f);
                b.visit(f);
            }
            Expr::Call(_, args) => args.iter().for_each(|a| a.visit(f)),
            Expr::Num(_) | Expr::Ref { .. } => {}
        }
    }

    /// Evaluates; a missing metric, a division by zero or a non-finite result is an error.
    pub fn eval(&self, env: &dyn Env) -> Result<f64, String> {
        let v = match self {
            Expr::Num(v) => *v,
            Expr::Ref { measure, key } => env.metric(measure, key)?,
            Expr::Neg(a) => -a.eval(env)?,
            Expr::Bin(a, op, b) => {
                let (a, b) = (a.eval(env)?, b.eval(env)?);
                match op {
                    Op::Add => a + b,
                    Op::Sub => a - b,
                    Op::Mul => a * b,
                    Op::Div if b == 0.0 => return Err(format!("division by zero in {self}")),
                    Op::Div => a / b,
                }
            }
            Expr::Call(func, args) => {
                let v: Vec<f64> = args.iter().map(|a| a.eval(env)).collect::<Result<_, _>>()?;
                match func {
                    Func::Min => v[0].min(v[1]),
                    Func::Max => v[0].max(v[1]),
                    Func::Abs => v[0].abs(),
                    Func::PointsAtFlip(m) => points_at_flip(&env.curve(m)?, v[0])
                        .map_err(|e| format!("points_at_flip({m}, {}): {e}", v[0]))?,
                }
            }
        };
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("{self} is not finite"))
        }
    }
}

/// How an error of [`points_at_flip`] begins when the sweep never reaches the FLIP asked
/// for: a measured outcome (the method cannot get that good, or that bad, in the sweep's
/// range), not a failure of the reproduction.
pub const NOT_REACHED: &str = "not reached: ";

/// The points at which a curve of `(flip, points)` pairs reaches `flip`: linear
/// interpolation of `ln points` against `ln flip` between the two targets around it (the
/// curve is sorted by FLIP first; an exact hit returns its points).
pub fn points_at_flip(curve: &[(f64, f64)], flip: f64) -> Result<f64, String> {
    let mut c: Vec<(f64, f64)> = curve
        .iter()
        .copied()
        .filter(|(f, p)| *f > 0.0 && *p > 0.0 && f.is_finite() && p.is_finite())
        .collect();
    c.sort_by(|a, b| a.0.total_cmp(&b.0));
    if c.len() < 2 || flip.is_nan() || flip <= 0.0 {
        return Err("needs two targets with FLIP > 0 and a FLIP > 0".into());
    }
    let (lo, hi) = (c[0].0, c[c.len() - 1].0);
    if flip < lo || flip > hi {
        return Err(format!(
            "{NOT_REACHED}outside the sweep's FLIP range {lo:.4}–{hi:.4}"
        ));
    }
    for w in c.windows(2) {
        let ((f0, p0), (f1, p1)) = (w[0], w[1]);
        if flip == f0 {
            return Ok(p0);
        }
        if flip == f1 {
            return Ok(p1);
        }
        if flip > f0 && flip < f1 {
            let t = (flip.ln() - f0.ln()) / (f1.ln() - f0.ln());
            return Ok((p0.ln() + t * (p1.ln() - p0.ln())).exp());
        }
    }
    Err("not bracketed".into())
}

impl fmt::Display for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Expr::Num(v) => write!(f, "{v}"),
            Expr::Ref { measure, key } => write!(f, "{measure}.{key}"),
            Expr::Neg(a) => write!(f, "-{a}"),
            Expr::Bin(a, op, b) => {
                let o = match op {
                    Op::Add => "+",
                    Op::Sub => "-",
                    Op::Mul => "*",
                    Op::Div => "/",
                };
                write!(f, "({a} {o} {b})")
            }
            Expr::Call(func, args) => {
                let name = match func {
                    Func::Min => "min",
                    Func::Max => "max",
                    Func::Abs => "abs",
                    Func::PointsAtFlip(m) => return write!(f, "points_at_flip({m}, {})", args[0]),
                };
                let a: Vec<String> = args.iter().map(ToString::to_string).collect();
                write!(f, "{name}({})", a.join(", "))
            }
        }
    }
}

struct Parser<'a> {
    s: &'a [u8],
    i: usize,
    text: &'a str,
}

impl Parser<'_> {
    fn ws(&mut self) {
        while self.i < self.s.len() && self.s[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }

    fn peek(&mut self) -> Option<u8> {
        self.ws();
        self.s.get(self.i).copied()
    }

    fn err(&self, expected: &str) -> String {
        match self.text.get(self.i..) {
            Some(rest) if !rest.is_empty() => {
                format!("'{}': expected {expected} at '{rest}'", self.text)
            }
            _ => format!("'{}': expected {expected} at the end", self.text),
        }
    }

    fn expr(&mut self) -> Result<Expr, String> {
        let mut a = self.term()?;
        while let Some(c @ (b'+' | b'-')) = self.peek() {
            self.i += 1;
            let op = if c == b'+' { Op::Add } else { Op::Sub };
            a = Expr::Bin(Box::new(a), op, Box::new(self.term()?));
        }
        Ok(a)
    }

    fn term(&mut self) -> Result<Expr, String> {
        let mut a = self.factor()?;
        while let Some(c @ (b'*' | b'/')) = self.peek() {
            self.i += 1;
            let op = if c == b'*' { Op::Mul } else { Op::Div };
            a = Expr::Bin(Box::new(a), op, Box::new(self.factor()?));
        }
        Ok(a)
    }

    fn factor(&mut self) -> Result<Expr, String> {
        match self.peek() {
            Some(b'-') => {
                self.i += 1;
                Ok(Expr::Neg(Box::new(self.factor()?)))
            }
            Some(b'(') => {
                self.i += 1;
                let e = self.expr()?;
                self.expect(b')')?;
                Ok(e)
            }
            Some(c) if c.is_ascii_digit() || c == b'.' => self.number(),
            Some(c) if c.is_ascii_alphabetic() || c == b'_' => self.name(),
            _ => Err(self.err("a number, a reference or '('")),
        }
    }

    fn expect(&mut self, c: u8) -> Result<(), String> {
        if self.peek() == Some(c) {
            self.i += 1;
            Ok(())
        } else {
            Err(self.err(&format!("'{}'", c as char)))
        }
    }

    fn number(&mut self) -> Result<Expr, String> {
        let start = self.i;
        while self.i < self.s.len() {
            let c = self.s[self.i];
            let exp_sign = (c == b'+' || c == b'-')
                && self.i > start
                && matches!(self.s[self.i - 1], b'e' | b'E');
            if c.is_ascii_digit() || c == b'.' || c == b'_' || c == b'e' || c == b'E' || exp_sign {
                self.i += 1;
            } else {
                break;
            }
        }
        let lit: String = self.text[start..self.i]
            .chars()
            .filter(|&c| c != '_')
            .collect();
        lit.parse().map(Expr::Num).map_err(|_| {
            self.i = start;
            self.err("a number")
        })
    }

    fn segment(&mut self) -> Option<String> {
        let start = self.i;
        while self.i < self.s.len()
            && (self.s[self.i].is_ascii_alphanumeric() || self.s[self.i] == b'_')
        {
            self.i += 1;
        }
        (self.i > start).then(|| self.text[start..self.i].to_string())
    }

    fn name(&mut self) -> Result<Expr, String> {
        let first = self.segment().ok_or_else(|| self.err("a name"))?;
        if self.s.get(self.i) == Some(&b'(') {
            self.i += 1;
            return self.call(&first);
        }
        let mut key = Vec::new();
        while self.s.get(self.i) == Some(&b'.') {
            self.i += 1;
            key.push(
                self.segment()
                    .ok_or_else(|| self.err("a metric name after '.'"))?,
            );
        }
        if key.is_empty() {
            return Err(format!(
                "'{}': '{first}' is not a reference: write measure.metric (e.g. {first}.median.points_drawn)",
                self.text
            ));
        }
        Ok(Expr::Ref {
            measure: first,
            key: key.join("."),
        })
    }

    fn call(&mut self, name: &str) -> Result<Expr, String> {
        let (func, arity) = match name {
            "min" => (Func::Min, 2),
            "max" => (Func::Max, 2),
            "abs" => (Func::Abs, 1),
            "points_at_flip" => {
                self.ws();
                let m = self
                    .segment()
                    .ok_or_else(|| self.err("a sweep measure's id"))?;
                self.expect(b',')?;
                let flip = self.expr()?;
                self.expect(b')')?;
                return Ok(Expr::Call(Func::PointsAtFlip(m), vec![flip]));
            }
            _ => {
                return Err(format!(
                    "'{}': unknown function '{name}' (known: min, max, abs, points_at_flip)",
                    self.text
                ));
            }
        };
        let mut args = vec![self.expr()?];
        while self.peek() == Some(b',') {
            self.i += 1;
            args.push(self.expr()?);
        }
        self.expect(b')')?;
        if args.len() != arity {
            return Err(format!(
                "'{}': {name} takes {arity} argument(s), not {}",
                self.text,
                args.len()
            ));
        }
        Ok(Expr::Call(func, args))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct E;
    impl Env for E {
        fn metric(&self, m: &str, k: &str) -> Result<f64, String> {
            match (m, k) {
                ("a", "x") => Ok(2.0),
                ("b", "median.points_drawn") => Ok(8.0),
                _ => Err(format!("no {m}.{k}")),
            }
        }
        fn curve(&self, m: &str) -> Result<Vec<(f64, f64)>, String> {
            match m {
                "s" => Ok(vec![(0.1, 1000.0), (0.01, 100_000.0), (0.001, 1e7)]),
                _ => Err(format!("{m} is not a sweep")),
            }
        }
    }

    fn ev(s: &str) -> Result<f64, String> {
        Expr::parse(s)?.eval(&E)
    }

    #[test]
    fn arithmetic_precedence_and_references() {
        assert_eq!(ev("1 + 2 * 3").unwrap(), 7.0);
        assert_eq!(ev("(1 + 2) * 3").unwrap(), 9.0);
        assert_eq!(ev("1 - b.median.points_drawn / a.x").unwrap(), -3.0);
        assert_eq!(ev("-a.x * -2").unwrap(), 4.0);
        assert_eq!(ev("1_000 * 2.5e-3").unwrap(), 2.5);
        assert_eq!(ev("min(a.x, 3) + max(1, abs(-4))").unwrap(), 6.0);
        assert_eq!(
            Expr::parse("1 - b.median.points_drawn / a.x")
                .unwrap()
                .measures(),
            vec!["b", "a"]
        );
    }

    #[test]
    fn points_at_flip_interpolates_in_log_log() {
        // Exact hit, and the geometric midpoint between two targets.
        assert_eq!(ev("points_at_flip(s, 0.01)").unwrap(), 100_000.0);
        let mid = ev("points_at_flip(s, 0.0316227766)").unwrap();
        assert!((mid - 10_000.0).abs() < 1.0, "{mid}");
        assert!(
            ev("points_at_flip(s, 0.5)")
                .unwrap_err()
                .contains("outside")
        );
        assert!(
            ev("points_at_flip(a, 0.5)")
                .unwrap_err()
                .contains("not a sweep")
        );
        assert_eq!(
            Expr::parse("points_at_flip(s, a.x)").unwrap().measures(),
            vec!["s", "a"]
        );
    }

    #[test]
    fn errors_say_what_and_where() {
        assert!(Expr::parse("1 +").unwrap_err().contains("at the end"));
        assert!(Expr::parse("a.x b.y").unwrap_err().contains("an operator"));
        assert!(Expr::parse("build").unwrap_err().contains("measure.metric"));
        assert!(
            Expr::parse("foo(1)")
                .unwrap_err()
                .contains("unknown function 'foo'")
        );
        assert!(Expr::parse("min(1)").unwrap_err().contains("takes 2"));
        assert!(Expr::parse("(1 + 2").unwrap_err().contains("')'"));
        assert!(Expr::parse("a.").unwrap_err().contains("after '.'"));
        assert!(
            ev("a.x / (a.x - 2)")
                .unwrap_err()
                .contains("division by zero")
        );
        assert!(ev("c.y").unwrap_err().contains("no c.y"));
    }
}
