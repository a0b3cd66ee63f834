//! Room in lists that are edited where they lie. Grown, such a list takes as much room
//! again as it needs, so that the edits that follow (a cut's new faces in a surface's
//! lists, a new layout in the last one's) land in room it already has instead of in a
//! copy of the whole list, whose fresh pages the frame would first-touch. Room not yet
//! written is address space only: its pages are not the process's until used.

/// Makes room in `list` for `additional` more items: when it has too little, for as
/// many again as it will then hold. Room it has is kept, and so are its items.
pub fn make_room<T>(list: &mut Vec<T>, additional: usize) {
    let needed = list.len().saturating_add(additional);
    if list.capacity() < needed {
        list.reserve_exact(needed.saturating_mul(2) - list.len());
    }
}

/// `list` emptied, with room for `count` items: its own allocation when that has the
/// room, else a new one with room to spare ([`make_room`]; the old items are not copied
/// over, as growing the list would).
pub fn emptied_with_room<T>(mut list: Vec<T>, count: usize) -> Vec<T> {
    list.clear();
    if list.capacity() < count {
        list = Vec::new();
    }
    make_room(&mut list, count);
    list
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A list with room enough keeps its allocation; one without grows to twice what it
    /// needs, items kept.
    #[test]
    fn a_list_grows_with_room_and_keeps_room_it_has() {
        let mut list: Vec<u32> = Vec::new();
        make_room(&mut list, 100);
        assert!(list.capacity() >= 200, "{}", list.capacity());
        list.extend(0..100);
        let (at, room) = (list.as_ptr(), list.capacity());
        make_room(&mut list, room - 100);
        assert_eq!((list.as_ptr(), list.capacity()), (at, room), "room it had");
        make_room(&mut list, room);
        assert!(list.capacity() >= 2 * (100 + room), "{}", list.capacity());
        assert!(list.iter().copied().eq(0..100));
    }

    /// An emptied list keeps its allocation when it has the room, and gets room to
    /// spare when it has not.
    #[test]
    fn an_emptied_list_keeps_its_room_or_gets_more() {
        let mut list: Vec<u32> = Vec::with_capacity(64);
        list.extend(0..10);
        let at = list.as_ptr();
        let list = emptied_with_room(list, 64);
        assert_eq!((list.len(), list.as_ptr()), (0, at));
        let list = emptied_with_room(list, 100);
        assert!(
            list.is_empty() && list.capacity() >= 200,
            "{}",
            list.capacity()
        );
    }
}
