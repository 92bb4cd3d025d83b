//! Following a planned path one move per step.

use rand::RngExt;
use rand_pcg::Pcg64Mcg;
use world::paths::{BreadthFirst, move_between};
use world::seed::purpose;
use world::{Action, Cell, Map, Seed};

/// Refused moves in a row after which an agent may give way. One refusal is the normal cost
/// of walking close behind another agent; two in a row usually mean two agents wanting each
/// other's cells, which waiting never resolves.
const REFUSALS_BEFORE_GIVING_WAY: u32 = 2;

/// When a blocked agent gives way (plans around the others): from then on, at each step, on
/// the toss of a coin from the agent's own stream. Two agents blocking each other that gave
/// way at the same step would step aside the same way and could meet again forever; with
/// coins, they soon give way at different steps and one of them lets the other pass.
#[derive(Clone, Debug)]
pub(crate) struct Impatience {
    coins: Pcg64Mcg,
}

impl Impatience {
    /// Agent `agent`'s stream under the episode's policy seed.
    pub(crate) fn of_agent(seed: Seed, agent: usize) -> Self {
        Self {
            coins: seed.child(purpose::POLICY).child(agent as u64).rng(),
        }
    }

    /// Whether to give way after `refusals` refused moves in a row.
    pub(crate) fn gives_way(&mut self, refusals: u32) -> bool {
        refusals >= REFUSALS_BEFORE_GIVING_WAY && self.coins.random_bool(0.5)
    }
}

/// The cells still ahead of an agent on its way to a goal.
///
/// Moves in the world either succeed or are refused (the agent stays), so an agent is always
/// on its route: after a refusal the same move is simply tried again next step.
#[derive(Clone, Debug, Default)]
pub(crate) struct Route {
    /// Goal first, next cell last, as [`BreadthFirst::path_to`] writes it.
    ahead: Vec<Cell>,
    /// Whether the last move asked for was a move, so that standing still means refused.
    moving: bool,
    refusals: u32,
}

impl Route {
    /// Plans the shortest path from the source of `search`'s last search to `goal`; false
    /// (and an empty route) when that search did not reach `goal`.
    pub(crate) fn plan(&mut self, search: &BreadthFirst, map: &Map, goal: Cell) -> bool {
        self.moving = false;
        self.refusals = 0;
        search.path_to(map, goal, &mut self.ahead)
    }

    pub(crate) fn clear(&mut self) {
        self.ahead.clear();
        self.moving = false;
        self.refusals = 0;
    }

    /// Whether no cell is left to walk to.
    pub(crate) fn is_finished(&self) -> bool {
        self.ahead.is_empty()
    }

    /// The cell the route ends on, until it is reached.
    fn goal(&self) -> Option<Cell> {
        self.ahead.first().copied()
    }

    /// Moves refused in a row, as of the last [`next_move`](Self::next_move).
    #[cfg(test)]
    fn refusals(&self) -> u32 {
        self.refusals
    }

    /// The move toward the next cell from `position`, forgetting the cells already reached;
    /// `Stay` once the goal is reached.
    pub(crate) fn next_move(&mut self, position: Cell) -> Action {
        if self.ahead.last() == Some(&position) {
            self.ahead.pop();
            self.refusals = 0;
        } else if self.moving {
            self.refusals += 1;
        }
        let action = match self.ahead.last() {
            Some(&next) => {
                let action = move_between(position, next);
                debug_assert!(action.is_some(), "{position:?} left its route at {next:?}");
                action.unwrap_or(Action::Stay)
            }
            None => Action::Stay,
        };
        self.moving = action != Action::Stay;
        action
    }

    /// The next move, planning a new path around `others` (agents' cells) first when the
    /// agent's moves keep being refused and it gives way. When no such path exists the route
    /// is kept and the agent waits.
    pub(crate) fn next_move_around(
        &mut self,
        position: Cell,
        impatience: &mut Impatience,
        others: &[Cell],
        search: &mut BreadthFirst,
        map: &Map,
    ) -> Action {
        let action = self.next_move(position);
        let Some(goal) = self.goal() else {
            return action;
        };
        if !impatience.gives_way(self.refusals) {
            return action;
        }
        let is_goal = |cell| (cell == goal).then_some(());
        if search
            .nearest_avoiding(map, position, others, is_goal)
            .is_some()
        {
            self.plan(search, map, goal);
            return self.next_move(position);
        }
        self.refusals = 0;
        action
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn map(text: &str) -> Map {
        Map::parse_text("t", text, Path::new("t.txt")).unwrap()
    }

    fn moved(at: Cell, action: Action) -> Cell {
        let (dx, dy) = action.delta();
        Cell::new((at.x as i64 + dx) as u16, (at.y as i64 + dy) as u16)
    }

    #[test]
    fn walks_to_the_goal_and_retries_refused_moves() {
        let m = map("...\n.#.\n...\n");
        let mut search = BreadthFirst::new(&m);
        search.explore(&m, Cell::new(0, 0));
        let mut route = Route::default();
        assert!(route.plan(&search, &m, Cell::new(2, 2)));
        let mut at = Cell::new(0, 0);
        let first = route.next_move(at);
        assert_eq!(route.next_move(at), first, "refused: the same move again");
        assert_eq!(route.refusals(), 1);
        for _ in 0..4 {
            at = moved(at, route.next_move(at));
            assert!(m.is_free(at));
        }
        assert_eq!(at, Cell::new(2, 2));
        assert_eq!(route.next_move(at), Action::Stay);
        assert!(route.is_finished());
    }

    #[test]
    fn plans_around_an_agent_that_keeps_blocking() {
        let m = map("...\n...\n");
        let mut search = BreadthFirst::new(&m);
        let (start, goal, blocker) = (Cell::new(0, 0), Cell::new(2, 0), Cell::new(1, 0));
        search.explore(&m, start);
        let mut route = Route::default();
        route.plan(&search, &m, goal);
        let others = [start, blocker];
        let mut impatience = Impatience::of_agent(Seed::new(1), 0);
        let moves: Vec<Action> = (0..40)
            .map(|_| route.next_move_around(start, &mut impatience, &others, &mut search, &m))
            .collect();
        assert_eq!(moves[..2], [Action::Right, Action::Right]);
        assert_eq!(
            moves.last(),
            Some(&Action::Up),
            "gave way, over the top row"
        );
        assert_eq!(route.goal(), Some(goal));
    }
}
