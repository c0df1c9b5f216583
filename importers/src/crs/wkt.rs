//! A small WKT tree parser: `KEYWORD[item, item, ...]` where an item is a quoted string, a
//! number, a bare word or a nested node. Accepts `[]` and `()` brackets. Used only to read what
//! `proj4wkt` does not give: authority codes, names, the datum's name and whether it carries a
//! `TOWGS84`, and the linear unit.
#[derive(Debug)]
pub(crate) enum Item {
    Text(String),
    Word(String),
    Node(Node),
}

#[derive(Debug)]
pub(crate) struct Node {
    pub keyword: String,
    pub items: Vec<Item>,
}

impl Node {
    pub fn name(&self) -> Option<&str> {
        match self.items.first() {
            Some(Item::Text(s)) => Some(s),
            _ => None,
        }
    }
    /// The `i`-th item as a number.
    pub fn number(&self, i: usize) -> Option<f64> {
        match self.items.get(i) {
            Some(Item::Word(w)) | Some(Item::Text(w)) => w.trim().parse().ok(),
            _ => None,
        }
    }
    pub fn children(&self) -> impl Iterator<Item = &Node> {
        self.items.iter().filter_map(|i| match i {
            Item::Node(n) => Some(n),
            _ => None,
        })
    }
    /// Depth-first search for the first node with this keyword.
    pub fn find(&self, keyword: &str) -> Option<&Node> {
        for c in self.children() {
            if c.keyword.eq_ignore_ascii_case(keyword) {
                return Some(c);
            }
            if let Some(n) = c.find(keyword) {
                return Some(n);
            }
        }
        None
    }
    /// The EPSG code of this node's own `AUTHORITY["EPSG","n"]` or `ID["EPSG",n]`.
    pub fn authority_epsg(&self) -> Option<u32> {
        self.children()
            .filter(|c| {
                c.keyword.eq_ignore_ascii_case("AUTHORITY") || c.keyword.eq_ignore_ascii_case("ID")
            })
            .find(|c| c.name().is_some_and(|n| n.eq_ignore_ascii_case("EPSG")))
            .and_then(|c| match c.items.get(1) {
                Some(Item::Text(s)) | Some(Item::Word(s)) => s.trim().parse().ok(),
                _ => None,
            })
    }
}

pub(crate) fn parse(text: &str) -> Option<Node> {
    let chars: Vec<char> = text.trim().trim_start_matches('\u{feff}').chars().collect();
    let mut pos = 0;
    let node = parse_node(&chars, &mut pos, 0)?;
    Some(node)
}

fn skip_ws(c: &[char], pos: &mut usize) {
    while *pos < c.len() && c[*pos].is_whitespace() {
        *pos += 1;
    }
}

fn parse_node(c: &[char], pos: &mut usize, depth: usize) -> Option<Node> {
    if depth > 64 {
        return None;
    }
    skip_ws(c, pos);
    let start = *pos;
    while *pos < c.len() && (c[*pos].is_ascii_alphanumeric() || c[*pos] == '_') {
        *pos += 1;
    }
    if *pos == start {
        return None;
    }
    let keyword: String = c[start..*pos].iter().collect();
    skip_ws(c, pos);
    if *pos >= c.len() || !(c[*pos] == '[' || c[*pos] == '(') {
        return None;
    }
    *pos += 1;
    let mut items = Vec::new();
    loop {
        skip_ws(c, pos);
        if *pos >= c.len() {
            return None;
        }
        match c[*pos] {
            ']' | ')' => {
                *pos += 1;
                break;
            }
            ',' => *pos += 1,
            '"' => {
                *pos += 1;
                let mut s = String::new();
                loop {
                    if *pos >= c.len() {
                        return None;
                    }
                    if c[*pos] == '"' {
                        // A doubled quote is an escaped quote.
                        if *pos + 1 < c.len() && c[*pos + 1] == '"' {
                            s.push('"');
                            *pos += 2;
                            continue;
                        }
                        *pos += 1;
                        break;
                    }
                    s.push(c[*pos]);
                    *pos += 1;
                }
                items.push(Item::Text(s));
            }
            _ => {
                // A nested node or a bare word (number, enumeration value).
                let save = *pos;
                let mut p2 = *pos;
                while p2 < c.len() && (c[p2].is_ascii_alphanumeric() || c[p2] == '_') {
                    p2 += 1;
                }
                let mut p3 = p2;
                skip_ws(c, &mut p3);
                if p2 > save && p3 < c.len() && (c[p3] == '[' || c[p3] == '(') {
                    items.push(Item::Node(parse_node(c, pos, depth + 1)?));
                } else {
                    let mut w = String::new();
                    while *pos < c.len() && !matches!(c[*pos], ',' | ']' | ')') {
                        w.push(c[*pos]);
                        *pos += 1;
                    }
                    items.push(Item::Word(w.trim().to_string()));
                }
            }
        }
    }
    Some(Node { keyword, items })
}
