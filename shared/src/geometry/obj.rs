//! The OBJ stream: many objects in one Wavefront OBJ text, read and written one object at a time.
//!
//! Conventions (specified with an example in `docs/formats/obj-stream.md`):
//! - each object starts with `o NAME`; vertex lines before the first `o` start an object named
//!   `object`;
//! - `f` indices are 1-based and global to the stream, as OBJ defines them (negative indices count
//!   back from the last vertex); a face may only use vertices of its own object, so that objects
//!   stream independently;
//! - `#@ key=value ...` lines inside an object are its attributes; other `#` lines are comments:
//!   those before the first object are the stream's provenance, passed through by every tool;
//! - `vt`, `vn`, `vp`, `g`, `s`, `l`, `p`, `usemtl`, `mtllib` are accepted and ignored; a face
//!   corner `i/t/n` uses `i`; a vertex is `v x y z`, with OBJ's optional weight only as 1;
//!   a UTF-8 byte-order mark may open the stream.
//!
//! The reader keeps one object in memory; the writer writes floats in the shortest text that
//! reads back to the same f64 (ryu), so a mesh round-trips exactly.

use crate::geometry::mesh::PolyMesh;
use crate::math::Vec3;
use crate::text::excerpt;
use std::io::{self, BufRead, Read, Write};
use thiserror::Error;

/// The longest line the reader takes, in bytes (a face of a million corners fits).
pub const MAX_LINE: usize = 16 << 20;

/// The most comment text one object may carry, in bytes (comments inside an object are kept
/// with it; those between objects pass through as they come).
pub const MAX_COMMENTS: usize = 16 << 20;

/// The most attributes (`#@ key=value`) one object may carry.
pub const MAX_ATTRIBUTES: usize = 10_000;

/// The largest coordinate magnitude the reader takes. A shape's moments of inertia go as the
/// fifth power of its size and a hull's orientation tests as the third: beyond this they
/// overflow a float, and the tools would write infinities or a broken hull.
pub const MAX_COORD: f64 = 1e50;

/// An OBJ reading error: an I/O failure, or bad text at a line, in an object.
#[derive(Debug, Error)]
pub enum ObjError {
    #[error("reading the OBJ stream: {0}")]
    Io(#[from] io::Error),
    #[error("line {line} (object '{object}'): {msg}")]
    Parse {
        line: u64,
        object: String,
        msg: String,
    },
}

/// One object of the stream, with the source line of each face (for error messages).
#[derive(Clone, Debug, Default)]
pub struct ObjObject {
    pub mesh: PolyMesh,
    /// Line of the `o` statement (or of the first vertex of an unnamed object).
    pub line: u64,
    pub face_lines: Vec<u64>,
    /// Plain `#` comment lines that stood inside the object, without the `#`.
    pub comments: Vec<String>,
}

/// What the stream holds, in order: comments between objects, and objects.
#[derive(Clone, Debug)]
pub enum Item {
    /// A `#` comment line outside any object, without the leading `#`.
    Comment(String),
    Object(ObjObject),
}

/// Reads an OBJ stream item by item.
pub struct ObjReader<R> {
    input: R,
    line_no: u64,
    buf: String,
    /// Vertices seen in earlier objects (the global index base of the current object).
    base: u64,
    current: Option<ObjObject>,
    /// Comments met after the current object's faces began: they belong to the object if more
    /// of it follows, to the stream if the object ends.
    trailing: Vec<String>,
    /// Bytes of comments the current object holds (with `trailing`).
    held_comments: usize,
    /// Items ready to hand out (a comment seen before any object, or a finished object).
    ready: std::collections::VecDeque<Item>,
    done: bool,
}

impl<R: BufRead> ObjReader<R> {
    pub fn new(input: R) -> Self {
        ObjReader {
            input,
            line_no: 0,
            buf: String::new(),
            base: 0,
            current: None,
            trailing: Vec::new(),
            held_comments: 0,
            ready: Default::default(),
            done: false,
        }
    }

    fn err(&self, msg: impl Into<String>) -> ObjError {
        let object = self
            .current
            .as_ref()
            .map_or_else(|| "-".to_string(), |o| excerpt(&o.mesh.name));
        ObjError::Parse {
            line: self.line_no,
            object,
            msg: msg.into(),
        }
    }

    fn finish_current(&mut self) {
        self.held_comments = 0;
        if let Some(obj) = self.current.take() {
            self.base += obj.mesh.vertices.len() as u64;
            self.ready.push_back(Item::Object(obj));
        }
        self.ready
            .extend(self.trailing.drain(..).map(Item::Comment));
    }

    fn current_or_implicit(&mut self) -> &mut ObjObject {
        let line = self.line_no;
        self.current.get_or_insert_with(|| ObjObject {
            mesh: PolyMesh::named("object"),
            line,
            ..Default::default()
        })
    }

    /// Reads lines until an item is ready or the input ends.
    fn fill(&mut self) -> Result<(), ObjError> {
        while self.ready.is_empty() && !self.done {
            self.buf.clear();
            let read = io::Read::by_ref(&mut self.input)
                .take(MAX_LINE as u64 + 1)
                .read_line(&mut self.buf)
                .map_err(|e| {
                    if e.kind() == io::ErrorKind::InvalidData {
                        self.line_no += 1;
                        self.err("not UTF-8 text")
                    } else {
                        ObjError::Io(e)
                    }
                })?;
            if read == 0 {
                self.done = true;
                self.finish_current();
                break;
            }
            if read > MAX_LINE {
                self.line_no += 1;
                return Err(self.err(format!("a line longer than {MAX_LINE} bytes")));
            }
            self.line_no += 1;
            let line = std::mem::take(&mut self.buf);
            let result = self.parse_line(&line);
            self.buf = line;
            result?;
        }
        Ok(())
    }

    fn parse_line(&mut self, line: &str) -> Result<(), ObjError> {
        // A byte-order mark may open the stream.
        let line = if self.line_no == 1 {
            line.strip_prefix('\u{feff}').unwrap_or(line)
        } else {
            line
        };
        let text = line.trim();
        if text.is_empty() {
            return Ok(());
        }
        if let Some(rest) = text.strip_prefix('#') {
            if let (Some(attrs), Some(obj)) = (rest.strip_prefix('@'), self.current.as_mut()) {
                for pair in attrs.split_ascii_whitespace() {
                    if obj.mesh.attrs.0.len() >= MAX_ATTRIBUTES {
                        let msg = format!("more than {MAX_ATTRIBUTES} attributes in one object");
                        return Err(ObjError::Parse {
                            line: self.line_no,
                            object: excerpt(&obj.mesh.name),
                            msg,
                        });
                    }
                    match pair.split_once('=') {
                        Some((k, v)) if !k.is_empty() => obj.mesh.attrs.set(k, v),
                        _ => {
                            return Err(
                                self.err(format!("attribute '{}' is not key=value", excerpt(pair)))
                            )
                        }
                    }
                }
            } else if let Some(obj) = self.current.as_mut() {
                self.held_comments += rest.len();
                if self.held_comments > MAX_COMMENTS {
                    return Err(self.err(format!(
                        "more than {MAX_COMMENTS} bytes of comments in one object"
                    )));
                }
                if obj.mesh.face_verts.is_empty() {
                    obj.comments.push(rest.to_string());
                } else {
                    self.trailing.push(rest.to_string());
                }
            } else {
                self.ready.push_back(Item::Comment(rest.to_string()));
            }
            return Ok(());
        }
        let mut tokens = text.split_ascii_whitespace();
        let tag = tokens.next().unwrap_or("");
        if tag != "o" && !self.trailing.is_empty() {
            if let Some(obj) = self.current.as_mut() {
                obj.comments.append(&mut self.trailing);
            }
        }
        match tag {
            "v" => {
                let mut xyz = [0.0f64; 3];
                for (i, slot) in xyz.iter_mut().enumerate() {
                    let tok = tokens
                        .next()
                        .ok_or_else(|| self.err(format!("vertex has {i} coordinates, needs 3")))?;
                    let x: f64 = tok.parse().map_err(|_| {
                        self.err(format!("bad vertex coordinate '{}'", excerpt(tok)))
                    })?;
                    if !x.is_finite() {
                        return Err(self.err(format!(
                            "vertex coordinate '{}' is not finite",
                            excerpt(tok)
                        )));
                    }
                    if x.abs() > MAX_COORD {
                        return Err(self.err(format!(
                            "vertex coordinate '{}' is beyond {MAX_COORD:e} (the range in \
                             which volumes and inertias stay finite)",
                            excerpt(tok)
                        )));
                    }
                    *slot = x;
                }
                // OBJ's optional weight w, which only a rational curve's vertex changes.
                let w = tokens.next();
                if let Some(extra) = w.filter(|w| w.parse::<f64>() != Ok(1.0)).or(tokens.next()) {
                    return Err(self.err(format!(
                        "vertex has more than x y z (and a weight of 1): '{}'",
                        excerpt(extra)
                    )));
                }
                self.current_or_implicit()
                    .mesh
                    .vertices
                    .push(Vec3::new(xyz[0], xyz[1], xyz[2]));
            }
            "f" => {
                let line_no = self.line_no;
                let base = self.base;
                let Some(obj) = self.current.as_mut() else {
                    return Err(self.err("face before any vertex"));
                };
                let nv = obj.mesh.vertices.len() as i64;
                let start = obj.mesh.face_verts.len();
                let mut bad = None;
                for tok in tokens {
                    let idx = tok.split('/').next().unwrap_or("");
                    let local = match idx.parse::<i64>() {
                        Ok(i) if i > 0 => i - 1 - base as i64,
                        Ok(i) if i < 0 => nv + i,
                        _ => {
                            bad = Some(format!("bad face index '{}'", excerpt(tok)));
                            break;
                        }
                    };
                    if local < 0 || local >= nv {
                        bad = Some(if local < 0 && idx.parse::<i64>().is_ok_and(|i| i > 0) {
                            format!("face index {idx} refers to a vertex of an earlier object; each object must own its vertices")
                        } else {
                            format!("face index {idx} is out of range (the object has {nv} vertices so far)")
                        });
                        break;
                    }
                    obj.mesh.face_verts.push(local as u32);
                }
                if bad.is_none() && obj.mesh.face_verts.len() - start < 3 {
                    bad = Some(format!(
                        "face has {} corners, needs at least 3",
                        obj.mesh.face_verts.len() - start
                    ));
                }
                if let Some(msg) = bad {
                    obj.mesh.face_verts.truncate(start);
                    return Err(self.err(msg));
                }
                obj.mesh.face_start.push(obj.mesh.face_verts.len() as u32);
                obj.face_lines.push(line_no);
            }
            "o" => {
                self.finish_current();
                let name = text[1..].trim();
                let name = if name.is_empty() { "object" } else { name };
                self.current = Some(ObjObject {
                    mesh: PolyMesh::named(name),
                    line: self.line_no,
                    ..Default::default()
                });
            }
            "vt" | "vn" | "vp" | "g" | "s" | "l" | "p" | "usemtl" | "mtllib" => {}
            other => return Err(self.err(format!("unknown OBJ statement '{}'", excerpt(other)))),
        }
        Ok(())
    }
}

impl<R: BufRead> Iterator for ObjReader<R> {
    type Item = Result<Item, ObjError>;

    fn next(&mut self) -> Option<Self::Item> {
        if let Err(e) = self.fill() {
            self.done = true;
            self.current = None;
            self.ready.clear();
            return Some(Err(e));
        }
        self.ready.pop_front().map(Ok)
    }
}

/// Writes an OBJ stream; keeps the global vertex count so that face indices are global (or,
/// from [`ObjWriter::relative`], writes them relative to each object's own vertices).
pub struct ObjWriter<W: Write> {
    out: W,
    base: u64,
    relative: bool,
    float: ryu::Buffer,
    int: itoa_like::Buffer,
}

impl<W: Write> ObjWriter<W> {
    pub fn new(out: W) -> Self {
        ObjWriter {
            out,
            base: 0,
            relative: false,
            float: ryu::Buffer::new(),
            int: itoa_like::Buffer::default(),
        }
    }

    /// A writer whose face indices are negative, counted back from each object's last vertex
    /// (OBJ's relative indices): its streams still read right when concatenated.
    pub fn relative(out: W) -> Self {
        ObjWriter {
            relative: true,
            ..ObjWriter::new(out)
        }
    }

    /// Writes a `#` comment line (`text` without the `#`).
    pub fn comment(&mut self, text: &str) -> io::Result<()> {
        writeln!(self.out, "#{text}")
    }

    /// Writes one object: `o`, its attributes, its comments, vertices and faces.
    pub fn object(&mut self, mesh: &PolyMesh, comments: &[String]) -> io::Result<()> {
        writeln!(self.out, "o {}", mesh.name)?;
        if !mesh.attrs.0.is_empty() {
            self.out.write_all(b"#@")?;
            for (k, v) in &mesh.attrs.0 {
                write!(self.out, " {k}={v}")?;
            }
            self.out.write_all(b"\n")?;
        }
        for c in comments {
            writeln!(self.out, "#{c}")?;
        }
        let mut line = Vec::with_capacity(96);
        for v in &mesh.vertices {
            line.clear();
            line.push(b'v');
            for x in v.iter() {
                line.push(b' ');
                line.extend_from_slice(self.float.format(*x).as_bytes());
            }
            line.push(b'\n');
            self.out.write_all(&line)?;
        }
        for f in mesh.faces() {
            line.clear();
            line.push(b'f');
            for &i in f {
                line.push(b' ');
                if self.relative {
                    line.push(b'-');
                    let back = mesh.vertices.len() as u64 - i as u64;
                    line.extend_from_slice(self.int.format(back));
                } else {
                    line.extend_from_slice(self.int.format(self.base + i as u64 + 1));
                }
            }
            line.push(b'\n');
            self.out.write_all(&line)?;
        }
        self.base += mesh.vertices.len() as u64;
        Ok(())
    }

    /// Flushes and hands back the inner writer.
    pub fn into_inner(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

/// Decimal formatting of unsigned integers without allocation.
mod itoa_like {
    #[derive(Default)]
    pub struct Buffer([u8; 20]);

    impl Buffer {
        pub fn format(&mut self, mut n: u64) -> &[u8] {
            let mut i = self.0.len();
            loop {
                i -= 1;
                self.0[i] = b'0' + (n % 10) as u8;
                n /= 10;
                if n == 0 {
                    break;
                }
            }
            &self.0[i..]
        }
    }
}

/// Reads every object of a stream (for small inputs and tests); comments are dropped.
pub fn read_all<R: BufRead>(input: R) -> Result<Vec<ObjObject>, ObjError> {
    let mut out = Vec::new();
    for item in ObjReader::new(input) {
        if let Item::Object(o) = item? {
            out.push(o);
        }
    }
    Ok(out)
}

/// Writes meshes as an OBJ stream into a string (for tests and small outputs).
pub fn to_string(meshes: &[PolyMesh]) -> String {
    let mut w = ObjWriter::new(Vec::new());
    for m in meshes {
        w.object(m, &[]).expect("writing to memory cannot fail");
    }
    String::from_utf8(w.into_inner().expect("writing to memory cannot fail"))
        .expect("OBJ text is UTF-8")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::cube;

    #[test]
    fn two_objects_round_trip_exactly() {
        let mut a = cube(1.0);
        a.vertices[0].x = 0.1 + 0.2; // a float whose shortest text is long
        a.attrs.set("k", 6);
        let mut b = cube(1e-7);
        b.name = "tiny cube".into();
        let text = to_string(&[a.clone(), b.clone()]);
        assert!(text.contains("f 9 11 12 10"), "indices are global:\n{text}");
        let back = read_all(text.as_bytes()).unwrap();
        assert_eq!(back.len(), 2);
        assert_eq!(back[0].mesh, a);
        assert_eq!(back[1].mesh, b);
    }

    #[test]
    fn comments_before_objects_are_items() {
        let text = "# made by hand\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let items: Vec<Item> = ObjReader::new(text.as_bytes())
            .map(|i| i.unwrap())
            .collect();
        assert!(matches!(&items[0], Item::Comment(c) if c == " made by hand"));
        assert!(
            matches!(&items[1], Item::Object(o) if o.mesh.name == "object" && o.face_lines == [5])
        );
    }

    #[test]
    fn a_comment_after_the_last_face_belongs_to_the_stream() {
        let text = "o a\n# inside a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n# between\no b\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 4 5 6\n# mid b\nf 6 5 4\n# at the end\n";
        let items: Vec<Item> = ObjReader::new(text.as_bytes())
            .map(|i| i.unwrap())
            .collect();
        let kinds: Vec<String> = items
            .iter()
            .map(|i| match i {
                Item::Comment(c) => format!("#{c}"),
                Item::Object(o) => format!("o {} {:?}", o.mesh.name, o.comments),
            })
            .collect();
        assert_eq!(
            kinds,
            [
                "o a [\" inside a\"]",
                "# between",
                "o b [\" mid b\"]",
                "# at the end"
            ]
        );
    }

    #[test]
    fn negative_and_slashed_indices() {
        let text = "o t\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf -3//1 -2//1 -1//1\nf 1/1 3/1 2/1\n";
        let o = &read_all(text.as_bytes()).unwrap()[0];
        assert_eq!(o.mesh.face(0), &[0, 1, 2]);
        assert_eq!(o.mesh.face(1), &[0, 2, 1]);
    }

    #[test]
    fn relative_streams_concatenate() {
        let tri = |name: &str, z: f64| {
            let v = vec![
                Vec3::new(0.0, 0.0, z),
                Vec3::new(1.0, 0.0, z),
                Vec3::new(0.0, 1.0, z),
            ];
            PolyMesh::from_faces(name, v, &[vec![0, 1, 2], vec![0, 2, 1]])
        };
        let write = |m: &PolyMesh| {
            let mut w = ObjWriter::relative(Vec::new());
            w.object(m, &[]).unwrap();
            w.into_inner().unwrap()
        };
        let (a, b) = (tri("a", 0.0), tri("b", 1.0));
        let mut both = write(&a);
        both.extend(write(&b));
        let back = read_all(&both[..]).unwrap();
        for (o, m) in back.iter().zip([&a, &b]) {
            assert_eq!(o.mesh.vertices, m.vertices);
            assert_eq!((o.mesh.face(0), o.mesh.face(1)), (m.face(0), m.face(1)));
        }
    }

    fn error_of(text: &str) -> String {
        read_all(text.as_bytes()).unwrap_err().to_string()
    }

    #[test]
    fn bad_input_names_line_and_object() {
        let e = error_of("o a\nv 0 0 0\nv 1 0 nan\n");
        assert!(
            e.contains("line 3") && e.contains("'a'") && e.contains("not finite"),
            "{e}"
        );
        let e = error_of("o a\nv 0 0\n");
        assert!(e.contains("line 2") && e.contains("2 coordinates"), "{e}");
        let e = error_of("o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
        assert!(e.contains("line 5") && e.contains("out of range"), "{e}");
        let e =
            error_of("o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no b\nv 0 0 1\nv 1 0 1\nf 1 4 5\n");
        assert!(e.contains("line 9") && e.contains("earlier object"), "{e}");
        let e = error_of("o a\nv 0 0 0\nbogus 1\n");
        assert!(e.contains("unknown OBJ statement 'bogus'"), "{e}");
        let e = error_of("o a\nv 0 0 0\nv 1 0 0\nf 1 2\n");
        assert!(e.contains("2 corners"), "{e}");
        let e = error_of("o a\n#@ nokey\n");
        assert!(e.contains("key=value"), "{e}");
    }
}
