//! Buffers of one file's lowering kept for the next file's ([`crate::Reader`]).
//!
//! Pass 3 (`objects`) sorts a file's sections into lists (object sections, sub-object sections
//! by object, their indices) and builds the list of the model's objects: vectors whose size
//! follows the file's, allocated and freed file after file. The allocator serves each size from
//! pages of its own, so that a file a little larger than the ones before it, or only of another
//! size, has its lists put on fresh pages (each a page fault), and allocating and freeing blocks
//! of tens of kilobytes is not cheap either. The [`Pool`] keeps those buffers, made from the
//! start with room for a file of the reader's expected size ([`crate::Reader::with_room`]), as pass
//! 1 keeps its own (`sections::Scratch`): room never written costs address space only.
//!
//! The model's small blocks are not kept: pools of the entry vectors by capacity and of the
//! boxed `EntryExtras`, handed to the next file's objects, were measured (`odgen check` on the
//! 61-file corpus) to cost more page faults than they saved (+2 and +25 on one thread): a
//! block kept alive keeps the allocator's page it lies on from serving the next file's blocks
//! of other sizes, which a model freed whole lets it do.

use super::sections::Section;
use crate::model::{Model, Object};

/// The buffers of pass 3, kept from one file to the next.
#[derive(Default)]
pub(crate) struct Pool {
    /// The list of objects of the last model given back (emptied), if any.
    pub objects: Vec<Object>,
    /// The lists `objects::lower_objects` sorts the sections into, emptied.
    pub lists: ObjectLists,
    /// The size of file the buffers are made for beyond the file's own needs (the reader's
    /// room: pass 3 knows the file's sections before it makes its lists, and sizes them for
    /// those, or for a file of this size if that is more).
    pub room: usize,
    /// The set of listed indices (`info::Lists`), emptied.
    pub listed: super::info::IndexSet,
}

/// The lists `objects::lower_objects` sorts a file's sections into, kept for the next file
/// (emptied: the sections they borrowed are gone with their file).
#[derive(Default)]
pub(crate) struct ObjectLists {
    /// The object sections and their indices.
    pub objects: Vec<(u16, &'static Section<'static>)>,
    /// The sub-object sections by object index.
    pub subs: Vec<(u16, (u8, &'static Section<'static>))>,
    /// The same, without the index.
    pub sub_sections: Vec<(u8, &'static Section<'static>)>,
    /// Their object indices.
    pub sub_indices: Vec<u16>,
    /// The indices of the object sections, sorted.
    pub object_indices: Vec<u16>,
}

impl Pool {
    /// Takes back the list of objects of `model` (emptied; the rest of the model is dropped).
    pub fn take_back(&mut self, model: Model) {
        let mut objects = model.objects.into_values();
        objects.clear();
        if objects.capacity() >= self.objects.capacity() {
            self.objects = objects;
        }
    }
}
